// Every language espeak-ng speaks, through the whole path (docs/languages.md).
//
// - Every voice file espeak-ng has (131 in Debian 12's espeak-ng-data) speaks the digits through
//   lipsync::speech (a fresh espeak-ng process each, as `lipsync say` and Speak use it), and the
//   phonemes it names (IPA for every voice but English's mnemonics) render without an unknown label.
// - A sentence in each of 22 languages (tonal Vietnamese, Cantonese and Mandarin, right-to-left Arabic,
//   Hebrew and Persian, Cyrillic, Greek, Devanagari, kana, Hangul...): at every bilabial key frame
//   the lips are sealed, in the channels and in ARKit, as on English speech.
// - The corpus tests/data/languages (espeak-ng's IPA timings, regenerate.py there), read without a
//   phone-set flag: front rounded vowels pucker more than their unrounded partners, open vowels
//   open, nasal vowels open like their oral partners, bilabial fricatives bring the lips near
//   without sealing them, closures sealed; through ARKit and the visemes.
// - MFA's IPA TextGrids (english_mfa, german_mfa, french_mfa, spanish_mfa phones) render through
//   `lipsync render` with and without --phone-set ipa, the same bytes; an unknown symbol is an
//   error naming it, the file and the line; `lipsync say --voice de` works.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include "../support/child_process.hpp"
#include "../support/closure_frames.hpp"
#include "../support/lip_measures.hpp"
#include "../support/lipsync_cli_test.hpp"
#include "lipsync/error.hpp"
#include "lipsync/face/face_mesh.hpp"
#include "lipsync/face/face_rig.hpp"
#include "lipsync/face/face_solver.hpp"
#include "lipsync/formats.hpp"
#include "lipsync/renderer.hpp"
#include "lipsync/segment.hpp"
#include "lipsync/speech/synthesizer.hpp"
#include "lipsync/visemes.hpp"

namespace lipsync {
namespace {

using ::testing::HasSubstr;

const ArticulationModel& model() { return ArticulationModel::builtin(); }

const std::vector<PhoneSet>& phone_sets() {
  static const std::vector<PhoneSet> sets = PhoneSet::builtin_all(model());
  return sets;
}

const PhoneSet& phone_set(const std::string& name) {
  for (const PhoneSet& set : phone_sets()) {
    if (set.name() == name) return set;
  }
  throw std::logic_error("no phone set " + name);
}

std::size_t arkit(std::string_view name) {
  return static_cast<std::size_t>(std::find(kArkitNames.begin(), kArkitNames.end(), name) - kArkitNames.begin());
}

std::size_t channel(std::string_view name) {
  for (std::size_t c = 0; c < model().channel_count(); ++c) {
    if (model().channels()[c].name == name) return c;
  }
  throw std::logic_error("no channel " + std::string(name));
}

std::string read_file(const std::filesystem::path& path) {
  std::ifstream file(path, std::ios::binary);
  std::stringstream text;
  text << file.rdbuf();
  return text.str();
}

struct Closures {
  std::size_t bilabial = 0;
  double worst_error = 0;  // largest closing-channel error at a closure key frame, share of range
  double worst_seal = 1;   // smallest mouthClose - jawOpen at a bilabial key frame
};

/// Checks every /p b m/ and /f v/ key frame of `track` as tests/core/closure_real_speech_test.cpp
/// does on English: closing channels within 5 % of the closure's targets, bilabials sealed in ARKit.
void check_closures(const std::string& where, const std::vector<Segment>& segments, const Track& track,
                    Closures& tally) {
  std::vector<float> shapes(kArkitNames.size());
  for (const auto& closure : testing::closure_frames(model(), segments, track)) {
    std::string worst_channel;
    const double error = testing::closure_error(model(), segments, track, closure, &worst_channel);
    tally.worst_error = std::max(tally.worst_error, error);
    EXPECT_LE(error, testing::kClosureTolerance)
        << where << ": /" << closure.phoneme << "/ at " << track.t_us[closure.frame] << " µs, " << worst_channel;
    if (closure.place != testing::ClosurePlace::bilabial) continue;
    ++tally.bilabial;
    model().retarget_to_arkit(track.frame_values(closure.frame), shapes);
    const double seal = shapes[arkit("mouthClose")] - shapes[arkit("jawOpen")];
    tally.worst_seal = std::min(tally.worst_seal, seal);
    EXPECT_GE(seal, -0.02) << where << ": /" << closure.phoneme << "/ at " << track.t_us[closure.frame] << " µs";
  }
}

Track render_speech(const speech::Synthesis& speech, std::vector<Segment>& segments) {
  LabeledUtterance phonemes = speech.phonemes;
  speech::cover_audio(phonemes, speech.audio.duration_us(), 30);
  segments = build_segments(phonemes, model(), phone_set(phonemes.phone_set));
  return render_track(model(), segments);
}

TEST(EspeakVoices, EveryVoiceSpeaksTheDigitsAndEveryPhonemeItNamesRenders) {
  const std::vector<speech::Voice> voices = speech::list_voices();
  ASSERT_GE(voices.size(), 131U) << "espeak-ng-data lists fewer voices than Debian 12's";
  // Voices whose language has no rules for reading digits (espeak-ng 1.51 says nothing for them):
  // their words for one to five (Cherokee in the Latin transliteration its rules read; Chuvash with
  // its Cyrillic ӗ ӑ ҫ: the Latin look-alikes ĕ ă ç were spelled out as "e breve" in English, which
  // lipsync now refuses).
  const std::map<std::string, const char*> number_words = {
      {"sem/he", "אחת שתיים שלוש ארבע חמש"},     {"trk/cv", "пӗрре иккӗ виҫҫӗ тӑваттӑ пиллӗк"},
      {"trk/nog", "бир эки уьш дёрт бес"},       {"trk/tk", "bir iki üç dört bäş"},
      {"iro/chr", "sagwu tali tsoi nvgi hisgi"}, {"art/qya", "minë atta neldë canta lempë"},
      {"art/sjn", "min tad neledh canad leben"}};
  std::size_t ipa_voices = 0, phonemes = 0, worded = 0;
  for (const speech::Voice& voice : voices) {
    SCOPED_TRACE(voice.identifier);
    speech::SynthesisOptions options;
    options.voice = voice.identifier;
    speech::Synthesis speech;
    try {
      speech = speech::synthesize("0 1 2 3 4 5 6 7 8 9 10 100", options);
      if (speech.phonemes.intervals.size() < 20 && number_words.contains(voice.identifier)) {
        speech = speech::synthesize(number_words.at(voice.identifier), options);
        ++worded;
      }
    } catch (const std::exception& error) {
      ADD_FAILURE() << error.what();
      continue;
    }
    EXPECT_EQ(speech.phonemes.phone_set, speech::phone_set_for_voice(voice.identifier));
    ipa_voices += speech.phonemes.phone_set == "ipa";
    phonemes += speech.phonemes.intervals.size();
    EXPECT_GE(speech.phonemes.intervals.size(), 12U);
    std::vector<Segment> segments;
    try {
      const Track track = render_speech(speech, segments);
      // Numbers have vowels: the jaw opens well beyond its rest (0.02).
      float widest = 0;
      for (std::size_t f = 0; f < track.frame_count(); ++f) {
        widest = std::max(widest, track.frame_values(f)[channel("jaw_rotation")]);
      }
      EXPECT_GT(widest, 0.2F);
    } catch (const InputError& error) {
      ADD_FAILURE() << error.what();
    }
  }
  std::printf("[ measured ] %zu voices, %zu of them named in IPA, %zu phonemes; %zu read number words\n", voices.size(),
              ipa_voices, phonemes, worded);
  EXPECT_GE(ipa_voices, voices.size() - 8);  // all but the English voices
}

TEST(EspeakVoices, ALanguageNameFromTheVoiceListSelectsItsVoice) {
  // `espeak-ng --voices` lists "en-gb" and "fr-fr" as languages; espeak_SetVoiceByName alone refuses them.
  for (const char* name : {"en-gb", "fr-fr", "de", "German", "gmw/de", "de+m2"}) {
    speech::SynthesisOptions options;
    options.voice = name;
    EXPECT_NO_THROW(speech::synthesize("1", options)) << name;
  }
  EXPECT_EQ(speech::phone_set_for_voice("en-us"), "espeak");
  EXPECT_EQ(speech::phone_set_for_voice("en+f3"), "espeak");
  EXPECT_EQ(speech::phone_set_for_voice("English (America)"), "espeak");
  EXPECT_EQ(speech::phone_set_for_voice("en-gb-x-rp"), "espeak");
  EXPECT_EQ(speech::phone_set_for_voice("gmw/en-US"), "espeak");
  EXPECT_EQ(speech::phone_set_for_voice("en-us+f3"), "espeak");
  EXPECT_EQ(speech::phone_set_for_voice("de"), "ipa");
  EXPECT_EQ(speech::phone_set_for_voice("fr-fr"), "ipa");
}

struct Sentence {
  const char* voice;
  const char* text;
};

// 22 languages: tonal (vi, yue, Mandarin in pinyin: Debian's espeak-ng-data has only the short
// Mandarin dictionary, which spells most characters out), right to left (ar, he, fa), non-Latin
// scripts (ru, el, hi, ja, ko, ar, he, fa, yue).
constexpr Sentence kSentences[] = {
    {"de", "Guten Morgen, wie geht es Ihnen? Die Brücke über dem Fluss ist schön."},
    {"fr-fr", "Bonjour, un bon vin blanc. Le petit prince a peur de la lune."},
    {"es", "Buenos días, ¿cómo estás? Me gusta la playa de Barcelona."},
    {"it", "Buongiorno, come stai? Mi piace la pizza con il pomodoro."},
    {"pt", "Bom dia, como vai? O pão é bom e o vinho também."},
    {"nl", "Goedemorgen, hoe gaat het met u? De appel is mooi."},
    {"sv", "God morgon, hur mår du? Mamma bakar bröd."},
    {"pl", "Dzień dobry, jak się masz? Proszę o bułkę i mleko."},
    {"ru", "Доброе утро, как дела? Мама мыла раму."},
    {"el", "Καλημέρα, τι κάνεις; Η μπάλα είναι μπλε."},
    {"tr", "Günaydın, nasılsınız? Bu bahçe çok güzel."},
    {"fi", "Hyvää huomenta, mitä kuuluu? Pöytä on pyöreä."},
    {"hu", "Jó reggelt, hogy van? A tükör fényes."},
    {"vi", "Xin chào, bạn khỏe không? Tôi muốn một bát phở."},
    {"cmn-latn-pinyin", "ni3 hao3, wo3 men2 ming2 tian1 qu4 bei3 jing1, ma1 ma1 mai3 mi3."},
    {"yue", "你好，我哋聽日去飲茶。"},
    {"ar", "صباح الخير، كيف حالك؟ أنا بخير."},
    {"he", "בוקר טוב, מה שלומך? אבא בבית."},
    {"fa", "صبح بخیر، حال شما چطور است؟ بابا به بازار رفت."},
    {"hi", "नमस्ते, आप कैसे हैं? मुझे पानी चाहिए।"},
    {"ja", "こんにちは、おげんきですか。"},
    {"ko", "안녕하세요, 반갑습니다."},
};

TEST(EspeakSentences, TwentyTwoLanguagesRenderWithLipsSealedAtEveryBilabialKeyFrame) {
  Closures tally;
  for (const Sentence& sentence : kSentences) {
    SCOPED_TRACE(sentence.voice);
    speech::SynthesisOptions options;
    options.voice = sentence.voice;
    const speech::Synthesis speech = speech::synthesize(sentence.text, options);
    EXPECT_GE(speech.phonemes.intervals.size(), 10U);
    std::vector<Segment> segments;
    const Track track = render_speech(speech, segments);
    check_closures(sentence.voice, segments, track, tally);
  }
  std::printf(
      "[ measured ] %zu languages: %zu bilabial key frames, worst closing channel %.2f %% off, worst "
      "mouthClose - jawOpen %.3f\n",
      std::size(kSentences), tally.bilabial, 100 * tally.worst_error, tally.worst_seal);
  EXPECT_GE(tally.bilabial, 40U);
}

// --- the corpus ------------------------------------------------------------------------------

struct Measured {
  std::string label;    // as the file has it
  std::string phoneme;  // the model phoneme
  std::vector<float> arkit;
  float jaw_open = 0, pucker = 0, lip_gap = 0;  // lip_gap: jawOpen - mouthClose
  std::string viseme;                           // Oculus viseme with the largest weight
  std::size_t frame = 0;                        // the track frame measured
};

struct CorpusFile {
  std::string name;
  std::string phone_set;
  std::vector<Segment> segments;
  Track track;
  std::vector<Measured> centres;  // at the frame nearest each interval's middle
};

const std::vector<CorpusFile>& corpus() {
  static const std::vector<CorpusFile> files = [] {
    std::vector<std::filesystem::path> paths;
    for (const auto& entry : std::filesystem::directory_iterator(std::string(LIPSYNC_TEST_DATA_DIR) + "/languages")) {
      if (entry.path().extension() == ".TextGrid" &&
          entry.path().filename().string().find("mfa") == std::string::npos) {
        paths.push_back(entry.path());
      }
    }
    std::sort(paths.begin(), paths.end());
    const VisemeClassifier oculus(model(), {.vocabulary = VisemeVocabulary::oculus});
    std::vector<CorpusFile> out;
    for (const auto& path : paths) {
      CorpusFile file;
      file.name = path.filename().string();
      const std::string text = read_file(path);
      const LabeledUtterance utterance = parse_utterance(text, detect_input_format(file.name, text), file.name);
      std::vector<std::string_view> labels;
      for (const auto& interval : utterance.intervals) labels.push_back(interval.label);
      const PhoneSet& set = detect_phone_set(phone_sets(), labels);
      file.phone_set = set.name();
      file.segments = build_segments(utterance, model(), set);
      file.track = render_track(model(), file.segments, {.fps = 60});
      std::vector<float> weights(oculus.viseme_count());
      for (const auto& interval : utterance.intervals) {
        const std::int64_t middle = (interval.start_us + interval.end_us) / 2;
        std::size_t nearest = 0;
        for (std::size_t f = 0; f < file.track.frame_count(); ++f) {
          if (std::llabs(file.track.t_us[f] - middle) < std::llabs(file.track.t_us[nearest] - middle)) nearest = f;
        }
        Measured m;
        m.frame = nearest;
        m.label = interval.label;
        m.phoneme = model().phoneme(*set.lookup(interval.label)).name;
        m.arkit.resize(kArkitNames.size());
        model().retarget_to_arkit(file.track.frame_values(nearest), m.arkit);
        m.jaw_open = m.arkit[arkit("jawOpen")];
        m.pucker = m.arkit[arkit("mouthPucker")];
        m.lip_gap = m.jaw_open - m.arkit[arkit("mouthClose")];
        oculus.weigh(file.track.frame_values(nearest), weights);
        m.viseme = oculus.names()[VisemeClassifier::winner(weights)];
        file.centres.push_back(std::move(m));
      }
      out.push_back(std::move(file));
    }
    return out;
  }();
  return files;
}

/// The centres of the corpus whose model phoneme is one of `phonemes` (or whose label, with stress
/// marks removed, is one of `labels` when given).
std::vector<const Measured*> centres_of(std::initializer_list<std::string_view> phonemes) {
  std::vector<const Measured*> out;
  for (const CorpusFile& file : corpus()) {
    for (const Measured& m : file.centres) {
      if (std::find(phonemes.begin(), phonemes.end(), m.phoneme) != phonemes.end()) out.push_back(&m);
    }
  }
  return out;
}

template <typename Field>
double mean(const std::vector<const Measured*>& centres, Field field) {
  double sum = 0;
  for (const Measured* m : centres) sum += field(*m);
  return centres.empty() ? 0.0 : sum / static_cast<double>(centres.size());
}

TEST(LanguageCorpus, IsReadAsIpaWithoutAPhoneSetFlag) {
  ASSERT_GE(corpus().size(), 8U);
  for (const CorpusFile& file : corpus()) EXPECT_EQ(file.phone_set, "ipa") << file.name;
}

TEST(LanguageCorpus, LipsAreSealedAtEveryBilabialKeyFrame) {
  Closures tally;
  for (const CorpusFile& file : corpus()) check_closures(file.name, file.segments, file.track, tally);
  std::printf(
      "[ measured ] corpus: %zu bilabial key frames, worst closing channel %.2f %% off, worst "
      "mouthClose - jawOpen %.3f\n",
      tally.bilabial, 100 * tally.worst_error, tally.worst_seal);
  EXPECT_GE(tally.bilabial, 30U);
}

TEST(LanguageCorpus, FrontRoundedVowelsPuckerMoreThanTheirUnroundedPartners) {
  const auto pucker = [](const Measured& m) { return m.pucker; };
  const std::pair<std::string_view, std::string_view> partners[] = {
      {"ipa_y", "iy"}, {"ipa_ʏ", "ih"}, {"ipa_ø", "ey"}, {"ipa_œ", "eh"}};
  std::size_t compared = 0;
  for (const auto& [rounded, unrounded] : partners) {
    const auto r = centres_of({rounded});
    const auto u = centres_of({unrounded});
    if (r.empty() || u.empty()) continue;  // espeak-ng's German writes its short ü as y, not ʏ
    ++compared;
    std::printf("[ measured ] mouthPucker /%s/ %.3f (%zu) vs /%s/ %.3f (%zu)\n", std::string(rounded).c_str(),
                mean(r, pucker), r.size(), std::string(unrounded).c_str(), mean(u, pucker), u.size());
    EXPECT_GT(mean(r, pucker), mean(u, pucker) + 0.2) << rounded << " vs " << unrounded;
    // Nearly every rounded vowel on its own, whatever its neighbours, puckers more than the
    // unrounded ones do on average (a short reduced /y/ between stops may not).
    const auto more =
        std::count_if(r.begin(), r.end(), [&](const Measured* m) { return m->pucker > mean(u, pucker) + 0.05; });
    EXPECT_GE(static_cast<double>(more), 0.8 * static_cast<double>(r.size())) << rounded;
  }
  EXPECT_GE(compared, 3U);
}

TEST(LanguageCorpus, OpenVowelsOpenTheJawWiderThanCloseOnes) {
  const auto jaw = [](const Measured& m) { return m.jaw_open; };
  const auto open = centres_of({"ae", "aa", "ah"});
  const auto close = centres_of({"iy", "uw", "ipa_y", "ipa_ɯ"});
  ASSERT_GE(open.size(), 10U);
  ASSERT_GE(close.size(), 10U);
  std::printf("[ measured ] jawOpen: open vowels %.3f (%zu), close vowels %.3f (%zu)\n", mean(open, jaw), open.size(),
              mean(close, jaw), close.size());
  EXPECT_GT(mean(open, jaw), 0.35);
  EXPECT_GT(mean(open, jaw), mean(close, jaw) + 0.2);
}

/// A label without stress marks and, if it has one, its nasal tilde; whether it had one.
std::pair<std::string, bool> oral_partner(const std::string& label) {
  std::string base;
  bool nasal = false;
  for (std::size_t i = 0; i < label.size();) {
    if (label.compare(i, 2, "\xCC\x83") == 0) {  // U+0303 combining tilde
      nasal = true;
      i += 2;
    } else if (label.compare(i, 2, "\xCB\x88") == 0 || label.compare(i, 2, "\xCB\x8C") == 0) {  // ˈ ˌ
      i += 2;
    } else {
      base += label[i++];
    }
  }
  return {base, nasal};
}

TEST(LanguageCorpus, NasalVowelsOpenLikeTheirOralPartners) {
  // French ɔ̃ ɛ̃ œ̃ ɑ̃, Portuguese ɐ̃ ũ: the mouth of the oral vowel (the lowered velum is not seen).
  // Compared within one file (one language, one voice's timing), where the oral partner occurs.
  std::size_t compared = 0;
  for (const CorpusFile& file : corpus()) {
    std::map<std::string, std::pair<double, int>> nasal_jaw, oral_jaw;  // partner label -> sum, count
    for (const Measured& m : file.centres) {
      const auto [base, nasal] = oral_partner(m.label);
      if (nasal) {
        EXPECT_EQ(m.phoneme, model().phoneme(*phone_set("ipa").lookup(base)).name) << file.name << " " << m.label;
      }
      auto& slot = (nasal ? nasal_jaw : oral_jaw)[base];
      slot.first += m.jaw_open;
      ++slot.second;
    }
    for (const auto& [base, sum] : nasal_jaw) {
      if (!oral_jaw.contains(base)) continue;
      const double nasal = sum.first / sum.second;
      const double oral = oral_jaw[base].first / oral_jaw[base].second;
      std::printf("[ measured ] %s: jawOpen /%s\u0303/ %.3f (%d) vs /%s/ %.3f (%d)\n", file.name.c_str(), base.c_str(),
                  nasal, sum.second, base.c_str(), oral, oral_jaw[base].second);
      EXPECT_NEAR(nasal, oral, 0.15) << file.name << " " << base;
      ++compared;
    }
  }
  EXPECT_GE(compared, 3U);
}

TEST(LanguageCorpus, BilabialFricativesBringTheLipsNearWithoutSealingThem) {
  const auto fricatives = centres_of({"ipa_β", "ipa_ɸ"});
  ASSERT_GE(fricatives.size(), 4U);
  const auto gap = [](const Measured& m) { return m.lip_gap; };
  const auto vowels = centres_of({"ae", "aa", "ah", "ey", "eh", "ow", "ao", "iy", "uw", "ipa_ɯ"});
  std::printf("[ measured ] jawOpen - mouthClose: /β ɸ/ %.3f (%zu), vowels %.3f\n", mean(fricatives, gap),
              fricatives.size(), mean(vowels, gap));
  for (const Measured* m : fricatives) {
    EXPECT_GT(m->lip_gap, 0.01) << m->label << ": sealed like a closure";
    EXPECT_LT(m->lip_gap, mean(vowels, gap)) << m->label << ": as open as a vowel";
  }
}

TEST(Targets, BilabialFricativesAndTrillBringTheLipsNearButOnlyClosuresSealThem) {
  // At their targets, in ARKit: /ɸ β ʙ/ leave a gap (jawOpen − mouthClose) a fraction of an open
  // vowel's, /m/ none; /ɱ ʋ ⱱ/ are the labiodental closures of /f v/ (key frames, lower lip on the teeth).
  const PhoneSet& ipa = phone_set("ipa");
  const auto gap = [&](std::string_view label) {
    std::vector<float> values(model().channel_count()), shapes(kArkitNames.size());
    const PhonemeSpec& spec = model().phoneme(*ipa.lookup(label));
    std::copy(spec.targets.begin(), spec.targets.end(), values.begin());
    model().retarget_to_arkit(values, shapes);
    return shapes[arkit("jawOpen")] - shapes[arkit("mouthClose")];
  };
  EXPECT_LE(gap("m"), 0.0F);
  for (const char* label : {"ɸ", "β", "ʙ"}) {
    EXPECT_EQ(model().phoneme(*ipa.lookup(label)).phoneme_class, PhonemeClass::consonant) << label;
    EXPECT_GT(gap(label), 0.01F) << label;
    EXPECT_LT(gap(label), 0.25F * gap("a")) << label;
  }
  for (const char* label : {"ɱ", "ʋ", "ⱱ"}) {
    const PhonemeSpec& spec = model().phoneme(*ipa.lookup(label));
    EXPECT_EQ(spec.phoneme_class, PhonemeClass::closure) << label;
    EXPECT_TRUE(spec.name == "f" || spec.name == "v") << label;
  }
}

/// ARKit mouthPucker + mouthFunnel at the middle of the consonant of "<vowel> <label> <vowel>"
/// (120 ms vowels, an 80 ms consonant, pauses around) rendered through the ipa phone set.
double rounding_at_consonant(std::string_view label, std::string_view vowel) {
  LabeledUtterance utterance;
  utterance.phone_set = "ipa";
  const std::pair<std::string_view, std::int64_t> phones[] = {
      {"", 200'000}, {vowel, 120'000}, {label, 80'000}, {vowel, 120'000}, {"", 200'000}};
  std::int64_t t_us = 0;
  for (const auto& [phone, duration_us] : phones) {
    utterance.intervals.push_back(LabeledInterval{std::string(phone), t_us, t_us + duration_us, 0});
    t_us += duration_us;
  }
  const std::vector<Segment> segments = build_segments(utterance, model(), phone_set("ipa"));
  const Track track = render_track(model(), segments);
  const std::int64_t middle_us = 200'000 + 120'000 + 40'000;
  std::size_t frame = 0;
  while (frame + 1 < track.t_us.size() && track.t_us[frame] < middle_us) ++frame;
  std::vector<float> shapes(kArkitNames.size());
  model().retarget_to_arkit(track.frame_values(frame), shapes);
  return shapes[arkit("mouthPucker")] + shapes[arkit("mouthFunnel")];
}

TEST(Labialisation, LabialisedConsonantsRoundTheLipsMoreThanTheirPlainPartners) {
  // ʷ acts through the features: kʷ is /k/ with the lips rounded as for /r/, so between spread /i/
  // and open /a/ alike the lips pucker and funnel more at kʷ than at k (render path, ARKit).
  for (const char* vowel : {"i", "a"}) {
    for (const char* plain : {"k", "ɡ", "t", "d", "s", "x", "n", "q", "ʁ"}) {
      const std::string labialised = std::string(plain) + "ʷ";
      const double rounded = rounding_at_consonant(labialised, vowel);
      const double spread = rounding_at_consonant(plain, vowel);
      EXPECT_GT(rounded, spread + 0.1) << "/" << vowel << " " << labialised << " " << vowel << "/: " << rounded
                                       << " against " << spread << " at /" << plain << "/";
    }
  }
  std::printf(
      "[ measured ] mouthPucker + mouthFunnel: /i kʷ i/ %.3f against /i k i/ %.3f; /a kʷ a/ %.3f against "
      "/a k a/ %.3f\n",
      rounding_at_consonant("kʷ", "i"), rounding_at_consonant("k", "i"), rounding_at_consonant("kʷ", "a"),
      rounding_at_consonant("k", "a"));
}

TEST(Labialisation, LabialisedLabialsKeepTheirClosureAndPlainConsonantsTheirPhoneme) {
  // A labial with ʷ (pʷ, mʷ, fʷ) has no partner of its own: the fallback drops ʷ and it is the
  // closure it was. The plain consonants keep their English phonemes.
  const PhoneSet& ipa = phone_set("ipa");
  for (const char* label : {"pʷ", "bʷ", "mʷ", "fʷ", "vʷ"}) {
    const std::string plain(label, std::string_view(label).size() - std::string_view("ʷ").size());
    ASSERT_TRUE(ipa.lookup(label)) << label;
    EXPECT_EQ(*ipa.lookup(label), *ipa.lookup(plain)) << label;
  }
  for (const char* label : {"k", "ɡ", "t", "s"}) {
    EXPECT_EQ(model().phoneme(*ipa.lookup(label)).name.find("ipa_"), std::string::npos) << label;
    EXPECT_EQ(model().phoneme(*ipa.lookup(std::string(label) + "ʷ")).name,
              "ipa_" + std::string(label == std::string_view("ɡ") ? "g" : label) + "ʷ")
        << label;
  }
  EXPECT_EQ(*ipa.lookup("kʷː"), *ipa.lookup("kʷ"));  // length falls back to the labialised consonant
}

TEST(LanguageCorpus, FrontRoundedVowelsGetARoundedVisemeAndTheirPartnersASpreadOne) {
  // Oculus has no front rounded viseme: /y ø/ fall on RR (slightly rounded lips over a nearly closed
  // jaw, the viseme of /r er/) or on ou/oh, never on the spread ih/E that /i e/ get.
  const auto share = [](const std::vector<const Measured*>& centres, std::initializer_list<std::string_view> visemes) {
    const auto n = std::count_if(centres.begin(), centres.end(), [&](const Measured* m) {
      return std::find(visemes.begin(), visemes.end(), m->viseme) != visemes.end();
    });
    return static_cast<double>(n) / static_cast<double>(centres.size());
  };
  const auto rounded = centres_of({"ipa_y", "ipa_ø"});
  const auto unrounded = centres_of({"iy", "ey"});
  ASSERT_GE(rounded.size(), 10U);
  ASSERT_GE(unrounded.size(), 10U);
  std::printf("[ measured ] Oculus: /y ø/ rounded (RR ou oh) %.0f %%, spread (ih E) %.0f %%; /i e/ spread %.0f %%\n",
              100 * share(rounded, {"RR", "ou", "oh"}), 100 * share(rounded, {"ih", "E"}),
              100 * share(unrounded, {"ih", "E"}));
  EXPECT_GE(share(rounded, {"RR", "ou", "oh"}), 0.75);
  EXPECT_EQ(share(rounded, {"ih", "E"}), 0.0);
  EXPECT_GE(share(unrounded, {"ih", "E"}), 0.75);
}

TEST(LanguageCorpus, OnTheSimulatedFaceClosuresSealAndRoundingNarrowsTheMouth) {
  // The physics face stepped through each track as lipsyncd's mesh stream does (subdivision 1):
  // lips sealed (gap <= 0.5 mm) at every bilabial key frame and the lower lip on the upper teeth
  // (<= 1 mm) at every labiodental one, as tests/face/face_closure_test.cpp measures English; the
  // mouth narrower (corner to corner, MediaPipe 61-291) at /y ø/ than at /i e/; /β ɸ/ open.
  using face::FaceMesh;
  static const FaceMesh mesh = face::build_face_mesh(face::FaceAsset::builtin(), 1);
  face::FaceSolver solver(mesh, face::FaceRig::builtin());
  std::size_t bilabial = 0, labiodental = 0;
  double worst_gap_m = 0, worst_teeth_m = 0;
  std::map<std::string, std::pair<double, int>> width_m, gap_m;  // phoneme -> sum, count at centres
  for (const CorpusFile& file : corpus()) {
    std::map<std::size_t, std::set<testing::ClosurePlace>> closure_at;
    for (const auto& closure : testing::closure_frames(model(), file.segments, file.track)) {
      closure_at[closure.frame].insert(closure.place);
    }
    std::multimap<std::size_t, const Measured*> centre_at;
    for (const Measured& m : file.centres) centre_at.emplace(m.frame, &m);
    solver.reset();
    std::int64_t previous_us = 0;
    for (std::size_t f = 0; f < file.track.frame_count(); ++f) {
      solver.step(file.track.frame_values(f), static_cast<double>(file.track.t_us[f] - previous_us) * 1e-6);
      previous_us = file.track.t_us[f];
      const auto x = solver.positions();
      for (auto [it, end] = centre_at.equal_range(f); it != end; ++it) {
        auto& width = width_m[it->second->phoneme];
        width.first += face::distance(x[61], x[291]);
        ++width.second;
        auto& gap = gap_m[it->second->phoneme];
        gap.first += face::lip_gap_m(solver);
        ++gap.second;
      }
      const auto closed = closure_at.find(f);
      if (closed == closure_at.end()) continue;
      const std::string where = file.name + " at " + std::to_string(file.track.t_us[f]) + " µs";
      // A closure at the very first frame (ru_mama starts with its /m/ at 0 µs) finds the face at rest:
      // the solver has had no time to move it. The channels are closed there (test above).
      if (file.track.t_us[f] == 0) continue;
      if (closed->second.contains(testing::ClosurePlace::bilabial)) {
        ++bilabial;
        worst_gap_m = std::max(worst_gap_m, face::lip_gap_m(solver));
        EXPECT_LE(face::lip_gap_m(solver), 0.0005) << where;
      }
      if (closed->second.contains(testing::ClosurePlace::labiodental)) {
        ++labiodental;
        worst_teeth_m = std::max(worst_teeth_m, face::lower_lip_to_upper_teeth_m(solver));
        EXPECT_LE(face::lower_lip_to_upper_teeth_m(solver), 0.001) << where;
      }
    }
  }
  const auto average = [](const std::map<std::string, std::pair<double, int>>& sums,
                          std::initializer_list<const char*> names) {
    double sum = 0;
    int count = 0;
    for (const char* name : names) {
      if (const auto it = sums.find(name); it != sums.end()) {
        sum += it->second.first;
        count += it->second.second;
      }
    }
    return count ? sum / count : 0.0;
  };
  const double rounded_width = average(width_m, {"ipa_y", "ipa_ø"});
  const double spread_width = average(width_m, {"iy", "ey"});
  std::printf(
      "[ measured ] face: %zu bilabial key frames, widest gap %.3f mm; %zu labiodental, farthest from the "
      "teeth %.3f mm; mouth width /y ø/ %.1f mm, /i e/ %.1f mm; lip gap /β ɸ/ %.2f mm, open vowels %.2f mm\n",
      bilabial, 1000 * worst_gap_m, labiodental, 1000 * worst_teeth_m, 1000 * rounded_width, 1000 * spread_width,
      1000 * average(gap_m, {"ipa_β", "ipa_ɸ"}), 1000 * average(gap_m, {"ae", "aa", "ah"}));
  EXPECT_GE(bilabial, 30U);
  EXPECT_LT(rounded_width, spread_width - 0.0015) << "front rounded vowels do not narrow the mouth";
  EXPECT_GT(average(gap_m, {"ipa_β", "ipa_ɸ"}), 0.0005) << "bilabial fricatives are sealed";
  EXPECT_LT(average(gap_m, {"ipa_β", "ipa_ɸ"}), 0.5 * average(gap_m, {"ae", "aa", "ah"}))
      << "bilabial fricatives open the lips like an open vowel";
}

// --- MFA TextGrids and the command line ------------------------------------------------------

class LanguagesCli : public testing::LipsyncCliTest {};

TEST_F(LanguagesCli, MfaIpaTextgridsRenderWithAndWithoutThePhoneSetFlag) {
  for (const char* name :
       {"mfa_english.TextGrid", "mfa_german.TextGrid", "mfa_french.TextGrid", "mfa_spanish.TextGrid"}) {
    SCOPED_TRACE(name);
    const std::string input = std::string(LIPSYNC_TEST_DATA_DIR) + "/languages/" + name;
    const auto detected = run({"render", input, "-o", "a.json"});
    ASSERT_EQ(detected.status, 0) << detected.err;
    const auto named = run({"render", input, "--phone-set", "ipa", "-o", "b.json"});
    ASSERT_EQ(named.status, 0) << named.err;
    EXPECT_EQ(read_file(dir_ / "a.json"), read_file(dir_ / "b.json"));
  }
}

TEST_F(LanguagesCli, AnUnknownSymbolIsAnErrorNamingItItsFileAndLine) {
  const std::string text = read_file(std::string(LIPSYNC_TEST_DATA_DIR) + "/languages/mfa_german.TextGrid");
  std::string bad = text;
  const std::size_t at = bad.find("text = \"ʏ\"");
  ASSERT_NE(at, std::string::npos);
  bad.replace(at, std::string("text = \"ʏ\"").size(), "text = \"ʏ☃\"");
  // The reader names the label's line (its `text =`, not its xmin two lines above).
  const std::size_t line =
      static_cast<std::size_t>(std::count(bad.begin(), bad.begin() + static_cast<long>(at), '\n')) + 1;
  const auto path = dir_ / "bad.TextGrid";
  std::ofstream(path, std::ios::binary) << bad;
  for (const bool named : {true, false}) {
    std::vector<std::string> args{"render", path.string(), "-o", "out.json"};
    if (named) args.insert(args.end(), {"--phone-set", "ipa"});
    const auto result = run(args);
    EXPECT_EQ(result.status, 1) << result.err;
    EXPECT_THAT(result.err, HasSubstr("bad.TextGrid:" + std::to_string(line)));
    EXPECT_THAT(result.err, HasSubstr("ʏ☃"));
  }
}

TEST_F(LanguagesCli, SaySpeaksGerman) {
  const auto result = run({"say", "Guten Morgen, wie geht es Ihnen?", "--voice", "de", "-o", "de.json"});
  ASSERT_EQ(result.status, 0) << result.err;
  EXPECT_THAT(read_file(dir_ / "de.json"), HasSubstr("\"frames\""));
}

}  // namespace
}  // namespace lipsync
