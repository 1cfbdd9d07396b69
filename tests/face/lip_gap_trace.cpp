// lip_gap_trace: the mouth of one utterance over time, for docs/face.md's figure
// (tools/face/plot_lip_gap.sh). Renders the file with the default model at 30 frames/s with key
// frames, steps the level-1 face frame by frame as lipsyncd's mesh stream does, and prints one
// tab-separated row per frame: time (s), frame kind, phoneme, inner-lip gap over the middle 20 mm
// (mm), lower lip to upper teeth (mm), jaw channel. The measures are the tests' (lip_measures.hpp).
//   lip_gap_trace FILE [PHONE_SET]   (phone set default: radio, Festival's and flite's)
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>

#include "../support/lip_measures.hpp"
#include "lipsync/error.hpp"
#include "lipsync/face/face_rig.hpp"
#include "lipsync/formats.hpp"
#include "lipsync/phone_set.hpp"
#include "lipsync/renderer.hpp"

int main(int argc, char** argv) {
  using namespace lipsync;
  if (argc < 2 || argc > 3) {
    std::fprintf(stderr, "usage: lip_gap_trace FILE [PHONE_SET]\n");
    return 2;
  }
  try {
    const std::string path = argv[1];
    std::ifstream file(path, std::ios::binary);
    if (!file) throw std::runtime_error(path + ": cannot open");
    std::stringstream text;
    text << file.rdbuf();
    const ArticulationModel& model = ArticulationModel::builtin();
    const auto phone_set = PhoneSet::builtin(argc == 3 ? argv[2] : "radio", model);
    if (!phone_set) throw std::runtime_error(std::string("unknown phone set ") + (argc == 3 ? argv[2] : "radio"));
    const auto segments =
        build_segments(parse_utterance(text.str(), detect_input_format(path, text.str()), path), model, *phone_set);
    const Track track = render_track(model, segments, {.fps = 30});
    const face::FaceMesh mesh = face::build_face_mesh(face::FaceAsset::builtin(), 1);
    face::FaceSolver solver(mesh, face::FaceRig::builtin());
    const std::size_t jaw = face::FaceRig::builtin().jaw_channel();
    std::printf("t_s\tkind\tphoneme\tlip_gap_mm\tlower_lip_to_upper_teeth_mm\tjaw\n");
    std::int64_t previous_us = 0;
    std::size_t segment = 0;
    for (std::size_t f = 0; f < track.frame_count(); ++f) {
      solver.step(track.frame_values(f), static_cast<double>(track.t_us[f] - previous_us) * 1e-6);
      previous_us = track.t_us[f];
      // A closure_end frame belongs to the closure that ends there.
      const std::int64_t probe = track.kinds[f] == FrameKind::closure_end ? track.t_us[f] - 1 : track.t_us[f];
      while (segment + 1 < segments.size() && segments[segment].end_us <= probe) ++segment;
      std::printf("%.6f\t%s\t%s\t%.4f\t%.4f\t%.4f\n", static_cast<double>(track.t_us[f]) * 1e-6,
                  std::string(to_string(track.kinds[f])).c_str(), model.phoneme(segments[segment].phoneme).name.c_str(),
                  1000 * face::lip_gap_m(solver), 1000 * face::lower_lip_to_upper_teeth_m(solver),
                  static_cast<double>(track.frame_values(f)[jaw]));
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "lip_gap_trace: error: %s\n", e.what());
    return 1;
  }
  return 0;
}
