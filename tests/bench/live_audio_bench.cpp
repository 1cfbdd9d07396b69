// What a live stream costs the server per second of audio, against the offline aligner on the same
// speech in the same run (docs/performance.md, "Live audio"): LibriVox's 7.1 s recording (a person
// reading, pocketsphinx-testdata) and flite's reading of the first Harvard sentence, heard by the
// LiveRecognizer in 20 ms pieces with the transcript (a grammar of the next words) and without it
// (the phone loop), each with the LiveRenderer's deadlines at the default budget; the baseline is
// align_speech on the whole recording. Counters: `rtf`, seconds of CPU per second of audio, whose
// inverse is the streams one core holds at real-time pace.
#include <benchmark/benchmark.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <memory>
#include <optional>
#include <string>

#include "lipsync/coarticulation.hpp"
#include "lipsync/live_renderer.hpp"
#include "lipsync/model.hpp"
#include "lipsync/phone_set.hpp"
#include "lipsync/speech/aligner.hpp"
#include "lipsync/speech/audio.hpp"
#include "lipsync/speech/live_recognizer.hpp"

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

void set_rtf(benchmark::State& state, const speech::PcmAudio& audio) {
  // Seconds of audio per second of CPU, inverted: CPU seconds per second of audio.
  state.counters["rtf"] =
      benchmark::Counter(static_cast<double>(state.iterations()) * static_cast<double>(audio.duration_us()) / 1e6,
                         benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}

void live(benchmark::State& state, const Speech& speech, bool with_transcript) {
  const ArticulationModel& model = ArticulationModel::builtin();
  static const PhoneSet arpabet = *PhoneSet::builtin("arpabet", model);
  const auto tables = std::make_shared<const CoarticulationTables>(model);
  speech::LiveRecognitionOptions options;
  options.sample_rate_hz = speech.audio.sample_rate_hz;
  if (with_transcript) options.transcript = speech.transcript;
  const auto piece = static_cast<std::size_t>(speech.audio.sample_rate_hz / 50);
  const auto& samples = speech.audio.samples;
  // The model is loaded once per stream; a stream of minutes pays it once, so it is left out.
  std::optional<speech::LiveRecognizer> recognizer;
  for (auto _ : state) {
    state.PauseTiming();
    recognizer.emplace(options, "bench");
    LiveRenderer renderer(tables, model, arpabet, "bench", {}, {});
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

BENCHMARK(BM_OfflineAlignmentLibrivoxTranscript)->Unit(benchmark::kMillisecond)->MinTime(2);
BENCHMARK(BM_LiveLibrivoxTranscript)->Unit(benchmark::kMillisecond)->MinTime(2);
BENCHMARK(BM_OfflineAlignmentLibrivoxAudioOnly)->Unit(benchmark::kMillisecond)->MinTime(2);
BENCHMARK(BM_LiveLibrivoxAudioOnly)->Unit(benchmark::kMillisecond)->MinTime(2);
BENCHMARK(BM_LiveFliteTranscript)->Unit(benchmark::kMillisecond)->MinTime(2);
BENCHMARK(BM_LiveFliteAudioOnly)->Unit(benchmark::kMillisecond)->MinTime(2);

}  // namespace

BENCHMARK_MAIN();
