// Track → simulated poses, and the face's colours; the design is in face_animation.hpp and
// docs/face.md. The poses' glTF binary is written by face_glb.cpp.
#include "lipsync/face/face_animation.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>

#include "lipsync/setting_ranges.hpp"

namespace lipsync::face {

std::array<float, 3> part_colour(FacePart part) {
  switch (part) {
    case FacePart::skin:
      return {0.80F, 0.56F, 0.44F};
    case FacePart::inner_lip:
      return {0.62F, 0.20F, 0.22F};
    case FacePart::mouth_cavity:
      return {0.22F, 0.04F, 0.05F};
    case FacePart::upper_teeth:
    case FacePart::lower_teeth:
      return {0.92F, 0.90F, 0.84F};
    case FacePart::tongue:
      return {0.75F, 0.30F, 0.32F};
    case FacePart::eye_white:
      return {0.90F, 0.88F, 0.84F};
    case FacePart::iris:
      return {0.28F, 0.20F, 0.12F};
    case FacePart::pupil:
      return {0.03F, 0.03F, 0.03F};
  }
  return {1.0F, 0.0F, 1.0F};
}

std::vector<std::array<float, 3>> vertex_colours(const FaceMesh& mesh) {
  static constexpr std::uint32_t kOuterLip[] = {61,  185, 40,  39,  37,  0,  267, 269, 270, 409,
                                                291, 375, 321, 405, 314, 17, 84,  181, 91,  146};
  constexpr std::array<float, 3> kLip{0.62F, 0.28F, 0.27F};
  std::vector<std::array<float, 3>> colours(mesh.vertex_count());
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
    colours[v] = part_colour(mesh.parts[v]);
    if (mesh.parts[v] != FacePart::skin) continue;
    // Even-odd rule in the x–y plane (the contour is a simple polygon seen from the front).
    const Vec3 p = mesh.rest_positions_m[v];
    bool inside = false;
    constexpr std::size_t kCount = std::size(kOuterLip);
    for (std::size_t k = 0, prev = kCount - 1; k < kCount; prev = k++) {
      const Vec3 a = mesh.rest_positions_m[kOuterLip[k]], b = mesh.rest_positions_m[kOuterLip[prev]];
      if ((a.y > p.y) != (b.y > p.y) && p.x < (b.x - a.x) * (p.y - a.y) / (b.y - a.y) + a.x) inside = !inside;
    }
    if (inside && p.z > mesh.mouth_centre_m.z - 0.01) colours[v] = kLip;
  }
  return colours;
}

void sample_track(const Track& track, std::int64_t t_us, std::span<float> out) {
  const std::size_t c = track.channel_count;
  if (track.frame_count() == 0) {
    std::fill(out.begin(), out.end(), 0.0F);
    return;
  }
  const auto it = std::upper_bound(track.t_us.begin(), track.t_us.end(), t_us);
  if (it == track.t_us.begin() || it == track.t_us.end()) {
    const auto values = track.frame_values(it == track.t_us.begin() ? 0 : track.frame_count() - 1);
    std::copy(values.begin(), values.end(), out.begin());
    return;
  }
  const auto k = static_cast<std::size_t>(it - track.t_us.begin());  // t_us[k-1] <= t < t_us[k]
  const double a =
      static_cast<double>(t_us - track.t_us[k - 1]) / static_cast<double>(track.t_us[k] - track.t_us[k - 1]);
  const auto v0 = track.frame_values(k - 1), v1 = track.frame_values(k);
  for (std::size_t i = 0; i < c; ++i)
    out[i] = static_cast<float>((1.0 - a) * static_cast<double>(v0[i]) + a * static_cast<double>(v1[i]));
}

FaceAnimation simulate_face_animation(const FaceMesh& mesh, const FaceRig& rig, const Track& track, int fps,
                                      FaceSolverParams params) {
  checked_fps(fps, "simulate_face_animation: fps");
  if (track.channel_count != rig.channel_count())
    throw std::invalid_argument("simulate_face_animation: the track's channels are not the rig's model's");
  const int substeps = (30 + fps - 1) / fps;  // the solver's step: 1/fps, or 1/30 s at most
  params.time_step_s = 1.0 / (static_cast<double>(fps) * substeps);
  FaceSolver solver(mesh, rig, params);
  FaceAnimation animation;
  animation.vertex_count = mesh.vertex_count();
  const std::int64_t end_us = track.frame_count() ? track.t_us.back() : 0;
  const auto frame_time = [&](std::int64_t k) {
    return static_cast<std::int64_t>(std::llround(static_cast<double>(k) * 1e6 / fps));
  };
  std::vector<float> channels(track.channel_count, 0.0F);
  // Start at rest, settled for 0.5 s on the first frame's values (a track starts in its rest pose).
  sample_track(track, frame_time(0), channels);
  solver.step(channels, 0.5);
  for (std::int64_t k = 0; k == 0 || frame_time(k - 1) < end_us; ++k) {
    if (k > 0) {
      for (int s = 1; s <= substeps; ++s) {
        const double t_s = (static_cast<double>(k - 1) + static_cast<double>(s) / substeps) / fps;
        sample_track(track, static_cast<std::int64_t>(std::llround(t_s * 1e6)), channels);
        solver.step(channels, params.time_step_s);
      }
    }
    animation.t_us.push_back(frame_time(k));
    const auto x = solver.positions();
    animation.positions.insert(animation.positions.end(), x.begin(), x.end());
  }
  return animation;
}

namespace {

std::uint64_t splitmix64(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30U)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27U)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31U);
}

double ease(double t) {
  const double c = std::clamp(t, 0.0, 1.0);
  return c * c * (3.0 - 2.0 * c);
}

}  // namespace

double eyelid_closure(const BlinkSettings& blinks, std::int64_t t_us) {
  if (!blinks.enabled || t_us < 0) return 0.0;
  std::int64_t start = kBlinkFirstUs;
  for (std::uint64_t k = 0;; ++k) {
    const std::uint64_t draw = splitmix64(blinks.seed + k) >> 11U;  // 53 bits
    const auto spread = static_cast<std::int64_t>(static_cast<double>(draw) * 0x1p-53 * kBlinkSpreadUs);
    if (k > 0) start += kBlinkMinIntervalUs + spread;
    if (t_us < start) return 0.0;
    const std::int64_t into = t_us - start;
    if (into < kBlinkCloseUs) return ease(static_cast<double>(into) / kBlinkCloseUs);
    if (into < kBlinkCloseUs + kBlinkHoldUs) return 1.0;
    if (into < kBlinkCloseUs + kBlinkHoldUs + kBlinkOpenUs)
      return 1.0 - ease(static_cast<double>(into - kBlinkCloseUs - kBlinkHoldUs) / kBlinkOpenUs);
  }
}

void close_eyelids(const FaceMesh& mesh, double closure, std::span<Vec3> pose) {
  if (!(closure > 0.0)) return;
  constexpr double kMarginM = 0.0005;
  for (std::size_t k = 0; k < mesh.blink_nodes.size(); ++k) {
    Vec3& p = pose[mesh.blink_nodes[k]];
    const Vec3 d = mesh.blink_offsets_m[k];
    p = {p.x + closure * d.x, p.y + closure * d.y, p.z + closure * d.z};
    // Outside the eyeball grown by the margin: scale the offset from its centre onto that surface.
    const EyeBall& ball = mesh.eyeballs[mesh.blink_eye[k]];
    const Vec3 a{ball.semi_axes_m.x + kMarginM, ball.semi_axes_m.y + kMarginM, ball.semi_axes_m.z + kMarginM};
    const Vec3 r{p.x - ball.centre_m.x, p.y - ball.centre_m.y, p.z - ball.centre_m.z};
    const double e = (r.x / a.x) * (r.x / a.x) + (r.y / a.y) * (r.y / a.y) + (r.z / a.z) * (r.z / a.z);
    if (e < 1.0 && r.z > 0.0) {
      // Forward along z onto the surface (the lid slides over the front of the ball).
      const double zz = a.z * std::sqrt(std::max(0.0, 1.0 - (r.x / a.x) * (r.x / a.x) - (r.y / a.y) * (r.y / a.y)));
      p.z = ball.centre_m.z + zz;
    }
  }
}

FaceTrackStepper::FaceTrackStepper(FaceSolver& solver, BlinkSettings blinks)
    : solver_(solver), blinks_(blinks), pose_(solver.positions().begin(), solver.positions().end()) {}

std::span<const Vec3> FaceTrackStepper::step(std::int64_t t_us, std::span<const float> channel_values) {
  solver_.step(channel_values, static_cast<double>(t_us - previous_t_us_) * 1e-6);
  previous_t_us_ = t_us;
  const auto x = solver_.positions();
  std::copy(x.begin(), x.end(), pose_.begin());
  close_eyelids(solver_.mesh(), eyelid_closure(blinks_, t_us), pose_);
  return pose_;
}

FaceAnimation simulate_track_frames(const FaceMesh& mesh, const FaceRig& rig, const Track& track,
                                    const FaceSolverParams& params, BlinkSettings blinks) {
  if (track.channel_count != rig.channel_count())
    throw std::invalid_argument("simulate_track_frames: the track's channels are not the rig's model's");
  FaceSolver solver(mesh, rig, params);
  FaceTrackStepper stepper(solver, blinks);
  FaceAnimation animation;
  animation.vertex_count = mesh.vertex_count();
  animation.t_us = track.t_us;
  animation.positions.reserve(track.frame_count() * mesh.vertex_count());
  for (std::size_t frame = 0; frame < track.frame_count(); ++frame) {
    const auto x = stepper.step(track.t_us[frame], track.frame_values(frame));
    animation.positions.insert(animation.positions.end(), x.begin(), x.end());
  }
  return animation;
}

FaceAnimation resample_face_animation(const FaceAnimation& animation, int fps) {
  checked_fps(fps, "resample_face_animation: fps");
  if (animation.frame_count() == 0) throw std::invalid_argument("resample_face_animation: the animation has no frames");
  const std::size_t nv = animation.vertex_count;
  const std::int64_t end_us = animation.t_us.back();
  const auto frame_time = [&](std::int64_t k) {
    return static_cast<std::int64_t>(std::llround(static_cast<double>(k) * 1e6 / fps));
  };
  FaceAnimation out;
  out.vertex_count = nv;
  std::size_t next = 0;  // the first frame after t
  for (std::int64_t k = 0; k == 0 || frame_time(k - 1) < end_us; ++k) {
    const std::int64_t t_us = frame_time(k);
    while (next < animation.frame_count() && animation.t_us[next] <= t_us) ++next;
    out.t_us.push_back(t_us);
    if (next == 0 || next == animation.frame_count() || animation.t_us[next - 1] == t_us) {
      const auto pose = animation.frame(next == 0 ? 0 : next - 1);
      out.positions.insert(out.positions.end(), pose.begin(), pose.end());
      continue;
    }
    const auto p0 = animation.frame(next - 1), p1 = animation.frame(next);
    const double a = static_cast<double>(t_us - animation.t_us[next - 1]) /
                     static_cast<double>(animation.t_us[next] - animation.t_us[next - 1]);
    for (std::size_t v = 0; v < nv; ++v) {
      out.positions.push_back(
          {p0[v].x + a * (p1[v].x - p0[v].x), p0[v].y + a * (p1[v].y - p0[v].y), p0[v].z + a * (p1[v].z - p0[v].z)});
    }
  }
  return out;
}

}  // namespace lipsync::face
