// What a live stream costs the server per second of audio, against the offline aligner on the same
// speech in the same run (docs/performance.md, "Live audio"): LibriVox's 7.1 s recording (a person
// reading, pocketsphinx-testdata) and flite's reading of the first Harvard sentence, heard by the
// LiveRecognizer in 20 ms pieces with the transcript (a grammar of the next words) and without it
// (the phone loop), each with the LiveRenderer's deadlines at the default budget; the baseline is
// align_speech on the whole recording. In another language (Festival's Italian "Il bambino beve
// un bicchiere di latte freddo ogni mattina.", tests/data/recorded_languages/it_1.wav) the
// LiveSynthesisAligner warps it live against espeak-ng's rendering of the transcript, against the
// offline warp (align_speech_to_synthesis) on the whole file. Counters: `rtf`, seconds of CPU per
// second of audio, whose inverse is the streams one core holds at real-time pace.
#include <benchmark/benchmark.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <memory>
#include <string>

#include "lipsync/coarticulation.hpp"
#include "lipsync/live_renderer.hpp"
#include "lipsync/model.hpp"
#include "lipsync/phone_set.hpp"
#include "lipsync/speech/aligner.hpp"
#include "lipsync/speech/audio.hpp"
#include "lipsync/speech/dtw_aligner.hpp"
#include "lipsync/speech/live_recognizer.hpp"
#include "lipsync/speech/live_synthesis_aligner.hpp"

namespace {

using namespace lipsync;

struct Speech {
  speech::PcmAudio audio;
  std::string transcript;
};

constexpr const char* kLibrivox =
    "/usr/share/pocketsphinx/test/data/librivox/sense_and_sensibility_01_austen_64kb-0870.wav";

const Speech& librivox() {
  static const Speech speech = [] {
    std::ifstream in(kLibrivox, std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    return Speech{speech::decode_wav(bytes, kLibrivox).audio,
                  "and mister john dashwood had then leisure to consider how much there might be prudently in his "
                  "power to do for them"};
  }();
  return speech;
}

const Speech& flite() {
  static const Speech speech = [] {
    const auto wav = std::filesystem::temp_directory_path() / "live_audio_bench.wav";
    const std::string text = "The birch canoe slid on the smooth planks.";
    const std::string command = "flite -voice slt -t \"" + text + "\" -o " + wav.string();
    if (std::system(command.c_str()) != 0) std::fprintf(stderr, "flite failed\n");
    std::ifstream in(wav, std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    std::filesystem::remove(wav);
    return Speech{speech::decode_wav(bytes, "flite.wav").audio, text};
  }();
  return speech;
}

const Speech& italian() {
  static const Speech speech = [] {
    const std::filesystem::path corpus = std::filesystem::path(LIPSYNC_TEST_DATA_DIR) / "recorded_languages";
    std::ifstream in(corpus / "it_1.wav", std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    return Speech{speech::decode_wav(bytes, "it_1.wav").audio,
                  "Il bambino beve un bicchiere di latte freddo ogni mattina."};
  }();
  return speech;
}

void set_rtf(benchmark::State& state, const speech::PcmAudio& audio) {
  // Seconds of audio per second of CPU, inverted: CPU seconds per second of audio.
  state.counters["rtf"] =
      benchmark::Counter(static_cast<double>(state.iterations()) * static_cast<double>(audio.duration_us()) / 1e6,
                         benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}

// A stream of `speech` heard by what `make_hearer` makes, in 20 ms pieces, and rendered live.
template <class MakeHearer>
void live_stream(benchmark::State& state, const Speech& speech, const std::string& phone_set, MakeHearer make_hearer) {
  const ArticulationModel& model = ArticulationModel::builtin();
  const PhoneSet phones = *PhoneSet::builtin(phone_set, model);
  const auto tables = std::make_shared<const CoarticulationTables>(model);
  const auto piece = static_cast<std::size_t>(speech.audio.sample_rate_hz / 50);
  const auto& samples = speech.audio.samples;
  // The model is loaded (or the transcript spoken by espeak-ng) once per stream; a stream of
  // minutes pays it once, so it is left out.
  std::unique_ptr<speech::LivePhoneSource> recognizer;
  for (auto _ : state) {
    state.PauseTiming();
    recognizer = make_hearer();
    LiveRenderer renderer(tables, model, phones, "bench", {}, {});
    Track track;
    track.channel_count = model.channel_count();
    state.ResumeTiming();
    for (std::size_t at = 0; at < samples.size(); at += piece) {
      recognizer->push(std::span(samples).subspan(at, std::min(piece, samples.size() - at)));
      for (const LabeledInterval& phoneme : recognizer->take_final()) renderer.push_final(phoneme, track);
      renderer.emit_until(recognizer->heard_us() - 150'000, recognizer->guess(), track);
      track.clear();
    }
    recognizer->finish();
    for (const LabeledInterval& phoneme : recognizer->take_final()) renderer.push_final(phoneme, track);
    renderer.finish(track);
    benchmark::DoNotOptimize(track.values.data());
  }
  set_rtf(state, speech.audio);
}

void live(benchmark::State& state, const Speech& speech, bool with_transcript) {
  speech::LiveRecognitionOptions options;
  options.sample_rate_hz = speech.audio.sample_rate_hz;
  if (with_transcript) options.transcript = speech.transcript;
  live_stream(state, speech, "arpabet", [&] { return std::make_unique<speech::LiveRecognizer>(options, "bench"); });
}

void offline(benchmark::State& state, const Speech& speech, bool with_transcript) {
  speech::AlignmentOptions options;
  if (with_transcript) options.transcript = speech.transcript;
  for (auto _ : state) benchmark::DoNotOptimize(speech::align_speech(speech.audio, "bench", options));
  set_rtf(state, speech.audio);
}

void BM_OfflineAlignmentLibrivoxTranscript(benchmark::State& state) { offline(state, librivox(), true); }
void BM_LiveLibrivoxTranscript(benchmark::State& state) { live(state, librivox(), true); }
void BM_OfflineAlignmentLibrivoxAudioOnly(benchmark::State& state) { offline(state, librivox(), false); }
void BM_LiveLibrivoxAudioOnly(benchmark::State& state) { live(state, librivox(), false); }
void BM_LiveFliteTranscript(benchmark::State& state) { live(state, flite(), true); }
void BM_LiveFliteAudioOnly(benchmark::State& state) { live(state, flite(), false); }
void BM_OfflineWarpItalianTranscript(benchmark::State& state) {
  speech::DtwAlignmentOptions options;
  options.transcript = italian().transcript;
  options.synthesis.voice = "it";
  for (auto _ : state) {
    benchmark::DoNotOptimize(speech::align_speech_to_synthesis(italian().audio, "bench", options));
  }
  set_rtf(state, italian().audio);
}
void BM_LiveWarpItalianTranscript(benchmark::State& state) {
  speech::LiveSynthesisOptions options;
  options.transcript = italian().transcript;
  options.synthesis.voice = "it";
  options.sample_rate_hz = italian().audio.sample_rate_hz;
  live_stream(state, italian(), "ipa",
              [&] { return std::make_unique<speech::LiveSynthesisAligner>(options, "bench"); });
}

BENCHMARK(BM_OfflineAlignmentLibrivoxTranscript)->Unit(benchmark::kMillisecond)->MinTime(2);
BENCHMARK(BM_LiveLibrivoxTranscript)->Unit(benchmark::kMillisecond)->MinTime(2);
BENCHMARK(BM_OfflineAlignmentLibrivoxAudioOnly)->Unit(benchmark::kMillisecond)->MinTime(2);
BENCHMARK(BM_LiveLibrivoxAudioOnly)->Unit(benchmark::kMillisecond)->MinTime(2);
BENCHMARK(BM_LiveFliteTranscript)->Unit(benchmark::kMillisecond)->MinTime(2);
BENCHMARK(BM_LiveFliteAudioOnly)->Unit(benchmark::kMillisecond)->MinTime(2);
BENCHMARK(BM_OfflineWarpItalianTranscript)->Unit(benchmark::kMillisecond)->MinTime(2);
BENCHMARK(BM_LiveWarpItalianTranscript)->Unit(benchmark::kMillisecond)->MinTime(2);

}  // namespace

BENCHMARK_MAIN();
