// Writes the seed corpus of fuzz_animate_stream (programs in the format of
// animate_program.hpp) into DIRECTORY, from the utterance files named after it
// (the test data: tests/data/closures/*, tests/data/formats/*). Per file, in
// its declared or detected phone set:
//   NAME.whole       settings, every phoneme in one chunk, end: the stream that works
//   NAME.chunked     chunks of three, a session with its metadata and a subscriber
//                    from the beginning, 60 fps, ARKit only, the viseme output
//   NAME.bad_middle  the phonemes in chunks of one, one in the middle given a
//                    start before the previous end
//   NAME.early_close the first half, then a half-close before `end`
// and, once, programs for what does not depend on a file: bad settings (fps
// 241, lookahead 9, an unknown model and phone set, a 300-byte session name),
// settings sent twice, an empty message, a message after `end`, raw bytes
// that are not an AnimateRequest, a cancel mid-stream, two producers of one
// session, a subscriber to a session that does not exist or whose metadata
// names another, and a small mesh stream.
#include <cstdio>
#include <fstream>
#include <functional>
#include <iterator>
#include <string>
#include <vector>

#include "animate_program.hpp"
#include "lipsync/error.hpp"
#include "lipsync/formats.hpp"
#include "lipsync/model.hpp"
#include "lipsync/phone_set.hpp"

namespace {

using lipsync::LabeledInterval;
using lipsync::fuzz::Metadata;
using lipsync::fuzz::Op;
using lipsync::fuzz::ProgramWriter;
namespace bits = lipsync::fuzz;

void settings(ProgramWriter& program, const std::string& phone_set, int slot = 0) {
  program.action(Op::settings, slot);
  program.u16(bits::kPhoneSet);
  program.string(phone_set);
}

/// A chunk of `phonemes`, each timed relative to the end of the one before
/// (their gaps and durations as in the file), but for `absolute_index`, whose
/// times are written as they are.
void chunk(ProgramWriter& program, const std::vector<LabeledInterval>& phonemes, std::int64_t previous_end_us,
           int slot = 0, std::size_t absolute_index = std::string::npos) {
  program.action(Op::phonemes, slot);
  program.u8(static_cast<std::uint8_t>(phonemes.size()));
  for (std::size_t i = 0; i < phonemes.size(); ++i) {
    const LabeledInterval& phoneme = phonemes[i];
    program.string(phoneme.label);
    if (i == absolute_index) {
      program.u8(1);
      program.i64(phoneme.start_us);
      program.i64(phoneme.end_us);
    } else {
      program.u8(0);
      program.varint(static_cast<std::uint64_t>(std::max<std::int64_t>(0, phoneme.start_us - previous_end_us)));
      program.varint(static_cast<std::uint64_t>(std::max<std::int64_t>(0, phoneme.end_us - phoneme.start_us)));
    }
    previous_end_us = phoneme.end_us;
  }
}

/// `phonemes` in chunks of `size` (each chunk at most 255 phonemes).
void chunks(ProgramWriter& program, const std::vector<LabeledInterval>& phonemes, std::size_t size, int slot = 0) {
  std::int64_t previous_end_us = 0;
  for (std::size_t begin = 0; begin < phonemes.size(); begin += size) {
    const auto end = std::min(phonemes.size(), begin + size);
    chunk(program,
          {phonemes.begin() + static_cast<std::ptrdiff_t>(begin), phonemes.begin() + static_cast<std::ptrdiff_t>(end)},
          previous_end_us, slot);
    previous_end_us = phonemes[end - 1].end_us;
  }
}

const std::vector<LabeledInterval> kHello = {
    {"", 0, 100'000},        {"HH", 100'000, 160'000},  {"AH0", 160'000, 220'000},
    {"L", 220'000, 300'000}, {"OW1", 300'000, 450'000}, {"P", 450'000, 520'000},
    {"B", 520'000, 600'000}, {"M", 600'000, 700'000},   {"", 700'000, 800'000}};

void write(const std::string& directory, const std::string& name, const ProgramWriter& program) {
  std::ofstream out(directory + "/" + name, std::ios::binary);
  out << program.bytes();
}

/// The four streams of one utterance file (see the top of the file).
void write_file_seeds(const std::string& directory, const std::string& name, const std::string& phone_set,
                      const std::vector<LabeledInterval>& phonemes) {
  ProgramWriter whole;
  settings(whole, phone_set);
  chunks(whole, phonemes, 255);
  whole.action(Op::end);
  write(directory, name + ".whole", whole);

  ProgramWriter chunked;
  chunked.action(Op::open);
  chunked.u8(static_cast<std::uint8_t>(Metadata::explicit_value));
  chunked.string(name);
  chunked.action(Op::settings);
  chunked.u16(bits::kPhoneSet | bits::kFps | bits::kSession | bits::kArkit | bits::kVisemes);
  chunked.u16(60);
  chunked.string(phone_set);
  chunked.string(name);
  chunked.u8(4);  // RHUBARB
  chunked.action(Op::subscribe);
  chunked.string(name);
  chunked.u8(1);  // START_FROM_BEGINNING
  chunked.u8(static_cast<std::uint8_t>(Metadata::same_as_body));
  chunks(chunked, phonemes, 3);
  chunked.action(Op::end);
  write(directory, name + ".chunked", chunked);

  ProgramWriter bad_middle;
  settings(bad_middle, phone_set);
  std::vector<LabeledInterval> shifted = phonemes;
  const std::size_t middle = shifted.size() / 2;
  if (middle > 0) shifted[middle].start_us = shifted[middle - 1].end_us - 1;
  for (std::size_t i = 0; i < shifted.size(); ++i) {
    chunk(bad_middle, {shifted[i]}, i == 0 ? 0 : shifted[i - 1].end_us, 0, i == middle ? 0 : std::string::npos);
  }
  bad_middle.action(Op::end);
  write(directory, name + ".bad_middle", bad_middle);

  ProgramWriter early_close;
  settings(early_close, phone_set);
  chunks(early_close, {phonemes.begin(), phonemes.begin() + static_cast<std::ptrdiff_t>(middle)}, 4);
  early_close.action(Op::half_close);
  write(directory, name + ".early_close", early_close);
}

/// Programs that do not depend on an utterance file.
void write_protocol_seeds(const std::string& directory) {
  const auto hello_after = [](const std::function<void(ProgramWriter&)>& first, bool end = true) {
    ProgramWriter program;
    first(program);
    chunks(program, kHello, 4);
    if (end) program.action(Op::end);
    return program;
  };
  write(directory, "bad_fps", hello_after([](ProgramWriter& p) {
          p.action(Op::settings);
          p.u16(bits::kFps);
          p.u16(241);
        }));
  write(directory, "bad_lookahead_closure", hello_after([](ProgramWriter& p) {
          p.action(Op::settings);
          p.u16(bits::kLookahead | bits::kClosureFraction);
          p.u8(9);
          p.f64(1.5);
        }));
  write(directory, "unknown_model_phone_set", hello_after([](ProgramWriter& p) {
          p.action(Op::settings);
          p.u16(bits::kModel | bits::kPhoneSet);
          p.string("no-such-model");
          p.string("klingon");
        }));
  write(directory, "long_session", hello_after([](ProgramWriter& p) {
          p.action(Op::settings);
          p.u16(bits::kSession);
          p.string(std::string(300, 's'));
        }));
  write(directory, "bad_viseme_shapes", hello_after([](ProgramWriter& p) {
          p.action(Op::settings);
          p.u16(bits::kVisemes | bits::kRhubarbShapes | bits::kFixedRate);
          p.u8(4);
          p.string("GGQ");
        }));
  write(directory, "settings_twice", hello_after([](ProgramWriter& p) {
          settings(p, "arpabet");
          settings(p, "arpabet");
        }));
  write(directory, "phonemes_first", hello_after([](ProgramWriter&) {}));
  write(directory, "empty_message", hello_after([](ProgramWriter& p) {
          settings(p, "");
          p.action(Op::raw);
          p.string("");
        }));
  write(directory, "not_an_animate_request", hello_after([](ProgramWriter& p) {
          settings(p, "");
          p.action(Op::raw);
          p.string("\xff\xff\xff\xff");
        }));
  ProgramWriter after_end = hello_after([](ProgramWriter& p) { settings(p, ""); });
  chunk(after_end, {{"AA1", 800'000, 900'000}}, 800'000);
  write(directory, "phoneme_after_end", after_end);
  {
    ProgramWriter program;
    program.action(Op::settings);
    program.u16(bits::kSession);
    program.string("cancelled");
    program.action(Op::subscribe);
    program.string("cancelled");
    program.u8(2);  // START_FROM_NOW
    program.u8(static_cast<std::uint8_t>(Metadata::none));
    chunks(program, kHello, 4);
    program.action(Op::cancel);
    write(directory, "cancel_mid_stream", program);
  }
  {
    ProgramWriter program;
    for (int slot : {0, 1}) {
      program.action(Op::settings, slot);
      program.u16(bits::kSession);
      program.string("shared");
    }
    for (int slot : {0, 1}) {
      chunks(program, kHello, 9, slot);
      program.action(Op::end, slot);
    }
    write(directory, "two_producers_one_session", program);
  }
  {
    ProgramWriter program;
    program.action(Op::subscribe);
    program.string("nobody");
    program.u8(0);
    program.u8(static_cast<std::uint8_t>(Metadata::none));
    program.action(Op::open, 1);
    program.u8(static_cast<std::uint8_t>(Metadata::explicit_value));
    program.string("other");
    program.action(Op::settings, 1);
    program.u16(bits::kSession);
    program.string("mine");
    program.action(Op::subscribe, 1);
    program.string("mine");
    program.u8(0);
    program.u8(static_cast<std::uint8_t>(Metadata::explicit_value));
    program.string("theirs");
    write(directory, "sessions_not_found_and_misrouted", program);
  }
  write(directory, "mesh_small", hello_after([](ProgramWriter& p) {
          p.action(Op::settings);
          p.u16(bits::kMesh | bits::kFps);
          p.u16(10);
          p.u8(0);  // subdivision 0
          p.u8(2);  // INT16
        }));
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: %s DIRECTORY [UTTERANCE_FILE...]\n", argv[0]);
    return 2;
  }
  const std::string directory = argv[1];
  const lipsync::ArticulationModel& model = lipsync::ArticulationModel::builtin();
  const std::vector<lipsync::PhoneSet> phone_sets = lipsync::PhoneSet::builtin_all(model);
  int written = 0;
  for (int i = 2; i < argc; ++i) {
    const std::string path = argv[i];
    std::ifstream in(path, std::ios::binary);
    const std::string content{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
    try {
      const lipsync::LabeledUtterance utterance =
          lipsync::parse_utterance(content, lipsync::detect_input_format(path, content), path);
      std::string phone_set = utterance.phone_set;
      if (phone_set.empty()) {
        std::vector<std::string_view> labels;
        for (const LabeledInterval& interval : utterance.intervals) labels.push_back(interval.label);
        phone_set = lipsync::detect_phone_set(phone_sets, labels).name();
      }
      if (utterance.intervals.empty()) continue;
      write_file_seeds(directory, path.substr(path.find_last_of('/') + 1), phone_set, utterance.intervals);
      ++written;
    } catch (const lipsync::InputError& error) {
      std::fprintf(stderr, "%s: skipped: %s\n", path.c_str(), error.what());
    }
  }
  write_protocol_seeds(directory);
  std::printf("seeds from %d utterance files in %s\n", written, directory.c_str());
  return 0;
}
