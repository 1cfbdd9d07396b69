// make_viewer_face: the face that the browser viewer poses from ARKit weights when a session does
// not carry the simulated mesh (docs/viewer.md, "The face"). Writes data/face/viewer_face.json.
//
// The viewer has only the 52 ARKit weights of each frame, so it needs a blendshape set: the rest
// mesh plus one vertex-delta vector per ARKit shape, posed as rest + Σ w_k Δ_k. We do not sculpt
// those deltas; we fit them to the physics face (docs/face.md). Real TTS utterances (the closure
// corpus of tests/data/closures: six Festival and six flite sentences full of /p b m f v/) are
// rendered on the uniform 30 fps grid, the face is simulated from their channel values
// (FaceSolver, subdivision 0: 771 vertices with lips, cavity, teeth and tongue), and the ARKit
// weights of the same frames come from the model's linear retargeting. The deltas are the
// weighted least-squares solution of
//     min Σ_frames s_f ‖(x_f − x_rest) − Σ_k w_{f,k} Δ_k‖² + λ Σ_k ‖Δ_k‖²,
// one small K × K system for all 3V coordinates (normal equations, LDLT). Frames at closure key
// frames weigh kClosureWeight times more, so that a /p b m/ closes the fitted lips too (the point
// of the face in the viewer). Shapes whose weight never exceeds kMinActiveWeight in the corpus
// are left out. Deltas are stored as integer micrometres. The fit's error (RMS and worst vertex
// error over all frames, and the inner-lip gap at closure frames) is written into the file and
// printed.
//
// Usage: make_viewer_face CORPUS_DIR OUT.json        (writes OUT.json)
//        make_viewer_face CORPUS_DIR --check FILE    (exit 1 if FILE differs from what it would write)
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "lipsync/face/face_animation.hpp"
#include "lipsync/face/face_mesh.hpp"
#include "lipsync/face/face_rig.hpp"
#include "lipsync/formats.hpp"
#include "lipsync/model.hpp"
#include "lipsync/phone_set.hpp"
#include "lipsync/renderer.hpp"
#include "lipsync/segment.hpp"

namespace {

using namespace lipsync;

constexpr int kFps = 30;
constexpr double kClosureWeight = 10.0;
constexpr double kMinActiveWeight = 0.02;
constexpr double kRidge = 1e-3;  // λ, in units of squared weight × frames
constexpr std::uint32_t kUpperInnerLip = 13, kLowerInnerLip = 14;

std::string read_file(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read " + path.string());
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

/// The corpus files in a fixed order (names sorted), Festival .lab and flite .psdur only.
std::vector<std::filesystem::path> corpus_files(const std::filesystem::path& dir) {
  std::vector<std::filesystem::path> files;
  for (const auto& entry : std::filesystem::directory_iterator(dir)) {
    const std::string name = entry.path().filename().string();
    if ((name.starts_with("festival_") && name.ends_with(".lab")) ||
        (name.starts_with("flite_") && !name.starts_with("flite_fast") && name.ends_with(".psdur"))) {
      files.push_back(entry.path());
    }
  }
  std::sort(files.begin(), files.end());
  if (files.empty()) throw std::runtime_error("no festival_*.lab or flite_*.psdur in " + dir.string());
  return files;
}

struct Samples {
  std::vector<std::vector<double>> arkit;  // per frame, 52
  std::vector<std::vector<double>> delta;  // per frame, 3V (positions − rest), metres
  std::vector<double> weight;              // per frame
  std::vector<bool> closure;               // frame at a /p b m/ closure key frame
};

Samples simulate_corpus(const std::vector<std::filesystem::path>& files, const face::FaceMesh& mesh) {
  const ArticulationModel& model = ArticulationModel::builtin();
  const face::FaceRig& rig = face::FaceRig::builtin();
  const std::vector<PhoneSet> phone_sets = PhoneSet::builtin_all(model);
  Samples samples;
  std::vector<float> channels(model.channel_count()), arkit(52);
  for (const auto& file : files) {
    const std::string text = read_file(file);
    const std::string source = file.filename().string();
    const LabeledUtterance utterance = parse_utterance(text, detect_input_format(source, text), source);
    std::vector<std::string_view> labels;
    for (const auto& interval : utterance.intervals) labels.push_back(interval.label);
    const PhoneSet& phone_set = detect_phone_set(phone_sets, labels);
    const std::vector<Segment> segments = build_segments(utterance, model, phone_set);
    const Track uniform = render_track(model, segments, {.fps = kFps, .fixed_rate = true});
    const Track keyed = render_track(model, segments, {.fps = kFps});
    const face::FaceAnimation animation = face::simulate_face_animation(mesh, rig, uniform, kFps);
    for (std::size_t k = 0; k < animation.frame_count(); ++k) {
      const std::int64_t t = animation.t_us[k];
      face::sample_track(uniform, t, channels);
      model.retarget_to_arkit(channels, arkit);
      samples.arkit.emplace_back(arkit.begin(), arkit.end());
      std::vector<double> delta(3 * mesh.vertex_count());
      const auto pose = animation.frame(k);
      for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
        delta[3 * v] = pose[v].x - mesh.rest_positions_m[v].x;
        delta[3 * v + 1] = pose[v].y - mesh.rest_positions_m[v].y;
        delta[3 * v + 2] = pose[v].z - mesh.rest_positions_m[v].z;
      }
      samples.delta.push_back(std::move(delta));
      // A closure frame: a grid frame within half a frame of a closure_start key frame of /p b m/
      // (the keyed track's closure frames; /f v/ close onto the teeth, not the lips).
      bool closure = false;
      for (std::size_t j = 0; j < keyed.frame_count(); ++j) {
        if (keyed.kinds[j] != FrameKind::closure_start) continue;
        if (std::llabs(keyed.t_us[j] - t) * kFps * 2 > 1'000'000) continue;
        const auto segment = std::find_if(segments.begin(), segments.end(), [&](const Segment& s) {
          return s.start_us <= keyed.t_us[j] && keyed.t_us[j] < s.end_us;
        });
        if (segment != segments.end()) {
          // p, b, m and their closure phonemes (pcl, bcl): the bilabials.
          const char first = model.phoneme(segment->phoneme).name.front();
          closure = closure || first == 'p' || first == 'b' || first == 'm';
        }
      }
      samples.closure.push_back(closure);
      samples.weight.push_back(closure ? kClosureWeight : 1.0);
    }
  }
  return samples;
}

nlohmann::json fit(const Samples& samples, const face::FaceMesh& mesh) {
  const std::size_t frames = samples.arkit.size(), coords = 3 * mesh.vertex_count();
  std::vector<std::size_t> active;
  for (std::size_t k = 0; k < 52; ++k) {
    double peak = 0;
    for (const auto& w : samples.arkit) peak = std::max(peak, w[k]);
    if (peak > kMinActiveWeight) active.push_back(k);
  }
  const auto shape_count = static_cast<Eigen::Index>(active.size());
  Eigen::MatrixXd weights(static_cast<Eigen::Index>(frames), shape_count),
      offsets(static_cast<Eigen::Index>(frames), static_cast<Eigen::Index>(coords));
  for (std::size_t f = 0; f < frames; ++f) {
    const double s = std::sqrt(samples.weight[f]);
    for (Eigen::Index k = 0; k < shape_count; ++k)
      weights(static_cast<Eigen::Index>(f), k) = s * samples.arkit[f][active[static_cast<std::size_t>(k)]];
    for (std::size_t c = 0; c < coords; ++c)
      offsets(static_cast<Eigen::Index>(f), static_cast<Eigen::Index>(c)) = s * samples.delta[f][c];
  }
  Eigen::MatrixXd normal = weights.transpose() * weights;
  normal.diagonal().array() += kRidge;
  const Eigen::MatrixXd deltas = normal.ldlt().solve(weights.transpose() * offsets);  // shape_count × 3V

  // Quantise as stored, then measure the error of what the viewer will draw.
  Eigen::MatrixXd stored = (deltas * 1e6).array().round() / 1e6;
  double squared = 0, worst = 0, closure_gap_sum = 0, closure_gap_max = 0, solver_gap_sum = 0;
  std::size_t closure_frames = 0;
  for (std::size_t f = 0; f < frames; ++f) {
    Eigen::RowVectorXd w(shape_count);
    for (Eigen::Index k = 0; k < shape_count; ++k) w(k) = samples.arkit[f][active[static_cast<std::size_t>(k)]];
    const Eigen::RowVectorXd posed = w * stored;
    for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
      double e2 = 0;
      for (std::size_t a = 0; a < 3; ++a) {
        const double e = posed(static_cast<Eigen::Index>(3 * v + a)) - samples.delta[f][3 * v + a];
        e2 += e * e;
      }
      squared += e2;
      worst = std::max(worst, std::sqrt(e2));
    }
    if (samples.closure[f]) {
      const auto gap = [&](const auto& d) {
        return (mesh.rest_positions_m[kUpperInnerLip].y + d(3 * kUpperInnerLip + 1)) -
               (mesh.rest_positions_m[kLowerInnerLip].y + d(3 * kLowerInnerLip + 1));
      };
      const double fitted = gap([&](std::size_t i) { return posed(static_cast<Eigen::Index>(i)); });
      const double solved = gap([&](std::size_t i) { return samples.delta[f][i]; });
      closure_gap_sum += fitted;
      closure_gap_max = std::max(closure_gap_max, fitted);
      solver_gap_sum += solved;
      ++closure_frames;
    }
  }
  const double rms = std::sqrt(squared / static_cast<double>(frames * mesh.vertex_count()));
  const auto mm = [](double m) { return std::round(m * 1e5) / 100.0; };  // 0.01 mm

  nlohmann::json shapes = nlohmann::json::array();
  for (Eigen::Index k = 0; k < shape_count; ++k) {
    std::vector<long> um(coords);
    for (std::size_t c = 0; c < coords; ++c) um[c] = std::lround(deltas(k, static_cast<Eigen::Index>(c)) * 1e6);
    shapes.push_back({{"name", std::string(kArkitNames[active[static_cast<std::size_t>(k)]])}, {"deltas_um", um}});
  }
  nlohmann::json rest = nlohmann::json::array(), triangles = nlohmann::json::array(), parts = nlohmann::json::array();
  for (const auto& p : mesh.rest_positions_m) {
    for (double c : {p.x, p.y, p.z}) rest.push_back(std::lround(c * 1e6));
  }
  for (const auto& t : mesh.triangles) {
    for (std::uint32_t i : t) triangles.push_back(i);
  }
  for (face::FacePart part : mesh.parts) parts.push_back(static_cast<int>(part));
  return {
      {"format", "lipsync-viewer-face 1"},
      {"about",
       "The physics face (subdivision 0) as a blendshape set for the browser viewer: rest + sum of "
       "ARKit weight x deltas, fitted to simulated real TTS speech by tools/face/make_viewer_face.cpp. "
       "Mesh: MediaPipe canonical face (Apache-2.0, see NOTICE)."},
      {"units", "micrometres"},
      {"vertex_count", mesh.vertex_count()},
      {"landmarks", {{"upper_inner_lip", kUpperInnerLip}, {"lower_inner_lip", kLowerInnerLip}}},
      {"parts_legend", {"skin", "inner_lip", "mouth_cavity", "upper_teeth", "lower_teeth", "tongue"}},
      {"rest_um", rest},
      {"triangles", triangles},
      {"parts", parts},
      {"blendshapes", shapes},
      {"fit",
       {{"frames", frames},
        {"closure_frames", closure_frames},
        {"rms_error_mm", mm(rms)},
        {"worst_vertex_error_mm", mm(worst)},
        {"closure_inner_lip_gap_mean_mm",
         mm(closure_frames ? closure_gap_sum / static_cast<double>(closure_frames) : 0)},
        {"closure_inner_lip_gap_max_mm", mm(closure_gap_max)},
        {"solver_closure_inner_lip_gap_mean_mm",
         mm(closure_frames ? solver_gap_sum / static_cast<double>(closure_frames) : 0)}}},
  };
}

}  // namespace

int main(int argc, char** argv) {
  const bool check = argc == 4 && std::string(argv[2]) == "--check";
  if (argc != 3 && !check) {
    std::cerr << "usage: make_viewer_face CORPUS_DIR OUT.json | make_viewer_face CORPUS_DIR --check FILE\n";
    return 2;
  }
  try {
    const face::FaceMesh mesh = face::build_face_mesh(face::FaceAsset::builtin(), 0);
    const nlohmann::json face = fit(simulate_corpus(corpus_files(argv[1]), mesh), mesh);
    const std::string text = face.dump() + "\n";
    std::cerr << "make_viewer_face: " << face["blendshapes"].size() << " blendshapes, fit " << face["fit"].dump()
              << "\n";
    if (check) {
      if (read_file(argv[3]) != text) {
        std::cerr << "make_viewer_face: " << argv[3]
                  << " is not what the tool writes now: regenerate it (docs/viewer.md, \"The face\")\n";
        return 1;
      }
      return 0;
    }
    std::ofstream out(argv[2], std::ios::binary);
    out << text;
    return out ? 0 : 1;
  } catch (const std::exception& error) {
    std::cerr << "make_viewer_face: " << error.what() << "\n";
    return 1;
  }
}
