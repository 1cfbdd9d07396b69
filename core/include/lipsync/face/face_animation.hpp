// The face over time: an animation track (channel values at frame times) simulated by FaceSolver
// on a uniform grid, and written out as a glTF 2.0 binary (.glb) that 3D tools open.
//
// simulate_face_animation() samples the track's channel values (linear interpolation between its
// frames, held before the first and after the last) at every solver substep, steps the solver,
// and records the pose at each frame of a uniform grid of `fps`. The substep is 1/(fps · s) with
// s = ceil(30 / fps): one solver step per frame at 30 frames/s and above, never longer than 1/30 s.
//
// write_face_glb() stores the mesh once (rest positions, UVs, per-part colours, triangles) and the
// motion as morph targets: one target per *key frame* (a frame that linear interpolation between
// the previous key and a later frame cannot reproduce within `key_tolerance_m`), and one weights
// animation with LINEAR interpolation whose weight vector is one-hot at each key time. Between two
// keys the weights blend exactly those two targets, i.e. the positions are linearly interpolated;
// a held pose costs one target instead of one per frame. Times in the sampler are float seconds
// (glTF's format) converted from the exact microseconds. Pure: writes to a std::ostream only.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <ostream>
#include <span>
#include <string>
#include <vector>

#include "lipsync/face/face_mesh.hpp"
#include "lipsync/face/face_rig.hpp"
#include "lipsync/face/face_solver.hpp"
#include "lipsync/track.hpp"

namespace lipsync::face {

/// Poses of the whole mesh (all vertices, mesh order) at strictly increasing times.
struct FaceAnimation {
  std::size_t vertex_count = 0;
  std::vector<std::int64_t> t_us;
  std::vector<Vec3> positions;  ///< frame_count() × vertex_count, metres

  std::size_t frame_count() const { return t_us.size(); }
  std::span<const Vec3> frame(std::size_t k) const { return {positions.data() + k * vertex_count, vertex_count}; }
};

/// The track's channel values at `t_us`: linear between frames, held outside. `out` has
/// track.channel_count elements.
void sample_track(const Track& track, std::int64_t t_us, std::span<float> out);

/// Simulates `track` from rest and records frames k = 0 … at t = round(k · 10⁶ / fps) µs, the
/// last one the first at or after the track's last frame time (a video covers the whole track). Throws
/// SettingError (a std::invalid_argument) for fps outside kFpsSetting or a track whose channel count differs from the
/// rig's.
FaceAnimation simulate_face_animation(const FaceMesh& mesh, const FaceRig& rig, const Track& track, int fps,
                                      FaceSolverParams params = {});

/// Blinks (docs/face.md, "Eyes"): a seeded schedule of spontaneous blinks, the same for a seed on
/// every path (stream, glb, video), or none for callers that drive the eyes themselves.
struct BlinkSettings {
  bool enabled = true;
  std::uint64_t seed = 1;  ///< the schedule's seed; the default is what lipsyncd and lipsync render use
};

/// How far the upper lids are shut at `t_us` (0 open … 1 shut) by the schedule of `blinks`: blink
/// k starts kBlinkFirstUs + Σ intervals, each interval kBlinkMinIntervalUs plus a uniform draw of
/// up to kBlinkSpreadUs from splitmix64(seed + k) (mean 3.5 s, about 17 blinks a minute, the rate
/// of a relaxed speaker); a blink shuts over 80 ms (smoothstep), stays shut 40 ms and opens over
/// 160 ms. 0 for every t when blinks are off or t < 0. Pure; O(t / 3.5 s).
double eyelid_closure(const BlinkSettings& blinks, std::int64_t t_us);
inline constexpr std::int64_t kBlinkFirstUs = 1'000'000;
inline constexpr std::int64_t kBlinkMinIntervalUs = 1'500'000;
inline constexpr std::int64_t kBlinkSpreadUs = 4'000'000;
inline constexpr std::int64_t kBlinkCloseUs = 80'000, kBlinkHoldUs = 40'000, kBlinkOpenUs = 160'000;

/// Closes the upper lids of `pose` (soft nodes in mesh order, as FaceSolver::positions()) by
/// `closure` (0 … 1): each of mesh.blink_nodes moves by closure · its offset and is kept 0.5 mm
/// outside its eyeball. No allocation.
void close_eyelids(const FaceMesh& mesh, double closure, std::span<Vec3> pose);

/// The face of a track's frames, one frame at a time: the rule every path that shows a track's face
/// follows (lipsyncd's mesh output, `lipsync render --mesh / --video / --still`), so that one input
/// and one set of settings give one face. From rest, one solver step per frame with
/// dt = t_i − t_{i−1} (t_{−1} = 0) and the channels held at the frame's values (FaceSolver::step
/// divides dt into substeps of at most its time step); the first frame, at t = 0, takes the
/// channels and moves no skin. The pose's lids are then closed by the blink schedule at t_i
/// (close_eyelids; the solver does not see the lids' motion: they are far from every muscle).
class FaceTrackStepper {
 public:
  /// `solver` must be at rest (new or reset) and outlive the stepper.
  explicit FaceTrackStepper(FaceSolver& solver, BlinkSettings blinks = {});
  /// Steps to the frame at `t_us` (after the previous one) with `channel_values`; returns the pose.
  std::span<const Vec3> step(std::int64_t t_us, std::span<const float> channel_values);

 private:
  FaceSolver& solver_;
  BlinkSettings blinks_;
  std::vector<Vec3> pose_;
  std::int64_t previous_t_us_ = 0;
};

/// The poses of every frame of `track` by FaceTrackStepper (the animation's times are the track's).
/// Throws std::invalid_argument for a track whose channel count differs from the rig's.
FaceAnimation simulate_track_frames(const FaceMesh& mesh, const FaceRig& rig, const Track& track,
                                    const FaceSolverParams& params = {}, BlinkSettings blinks = {});

/// `animation` seen on a uniform grid, as a video shows it: frames k = 0 … at
/// t = round(k · 10⁶ / fps) µs, the last one the first at or after the animation's last time; each
/// pose linear between the two frames around it (what a glTF player shows between two keys), held
/// after the end. Throws SettingError for fps outside kFpsSetting, std::invalid_argument for an
/// empty animation.
FaceAnimation resample_face_animation(const FaceAnimation& animation, int fps);

struct GlbOptions {
  /// A frame becomes a key when linear interpolation from the previous key misses any vertex of an
  /// intermediate frame by more than this (0 keeps every frame).
  double key_tolerance_m = 0.0001;
  std::string name = "lipsync face";
};

struct GlbSummary {
  std::size_t key_frames = 0;
  std::size_t bytes = 0;
};

/// Writes `animation` of `mesh` as a glTF 2.0 binary. Throws std::invalid_argument for an empty
/// animation or a vertex count that differs from the mesh's.
GlbSummary write_face_glb(std::ostream& out, const FaceMesh& mesh, const FaceAnimation& animation,
                          const GlbOptions& options = {});

/// Linear RGB colour (0..1) of a mesh part, shared by the glTF export and the rasteriser.
std::array<float, 3> part_colour(FacePart part);
/// Per-vertex linear RGB: the part's colour, with the skin inside the outer lip contour (landmarks
/// 61 185 40 39 37 0 267 269 270 409 291 375 321 405 314 17 84 181 91 146, seen from the front at
/// rest) in a lip colour.
std::vector<std::array<float, 3>> vertex_colours(const FaceMesh& mesh);

}  // namespace lipsync::face
