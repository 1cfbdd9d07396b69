// Writes the seed corpus of fuzz_render_request (binary RenderRequest
// messages) into the directory given as its argument: the settings the server
// tests use, with the phonemes of tests/data/cli/hello.json.
#include <cstdio>
#include <fstream>
#include <string>

#include "lipsync/v1/lipsync.pb.h"

namespace {

void add_hello(lipsync::v1::RenderRequest& request) {
  const struct {
    const char* label;
    long start_us, end_us;
  } phonemes[] = {{"", 0, 100'000},        {"HH", 100'000, 160'000},  {"AH0", 160'000, 220'000},
                  {"L", 220'000, 300'000}, {"OW1", 300'000, 450'000}, {"P", 450'000, 520'000},
                  {"B", 520'000, 600'000}, {"M", 600'000, 700'000},   {"", 700'000, 800'000}};
  for (const auto& p : phonemes) {
    lipsync::v1::Phoneme* phoneme = request.add_phonemes();
    phoneme->set_label(p.label);
    phoneme->set_start_us(p.start_us);
    phoneme->set_end_us(p.end_us);
  }
}

void write(const std::string& directory, const std::string& name, const lipsync::v1::RenderRequest& request) {
  std::ofstream out(directory + "/" + name, std::ios::binary);
  request.SerializeToOstream(&out);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s DIRECTORY\n", argv[0]);
    return 2;
  }
  const std::string directory = argv[1];
  lipsync::v1::RenderRequest plain;
  add_hello(plain);
  write(directory, "render_default", plain);

  lipsync::v1::RenderRequest tuned = plain;
  lipsync::v1::AnimationSettings& settings = *tuned.mutable_settings();
  settings.set_fps(60);
  settings.set_lookahead(2);
  settings.set_closure_fraction(0.5);
  settings.set_session("seed");
  settings.mutable_outputs()->set_arkit(true);
  write(directory, "render_tuned", tuned);

  lipsync::v1::RenderRequest fixed = plain;
  fixed.mutable_settings()->set_fixed_rate(true);
  fixed.mutable_settings()->set_phone_set("arpabet");
  fixed.mutable_settings()->set_fps(240);
  write(directory, "render_fixed_rate", fixed);

  lipsync::v1::RenderRequest timit;
  timit.mutable_settings()->set_phone_set("timit");
  for (const char* label : {"h#", "pcl", "p", "iy", "bcl", "b", "h#"}) {
    lipsync::v1::Phoneme* phoneme = timit.add_phonemes();
    const long start_us = timit.phonemes_size() == 1 ? 0 : timit.phonemes(timit.phonemes_size() - 2).end_us();
    phoneme->set_label(label);
    phoneme->set_start_us(start_us);
    phoneme->set_end_us(start_us + 70'000);
  }
  write(directory, "render_timit", timit);
  return 0;
}
