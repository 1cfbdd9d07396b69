// The mesh output: the physics face (lipsync::face, docs/face.md) driven by a
// stream's frames.
//
// FaceLibrary holds what every stream shares: the FaceMesh and its wire
// topology per subdivision level (built on first use, once, under a
// std::once_flag per level) and the FaceRig validated per model. A FaceStream
// is one stream's FaceSolver (its own state: the face moves with that stream
// only); it steps once per released frame with dt = t_i − t_{i−1} (t_{−1} = 0:
// key frames make the steps uneven; FaceSolver rounds each to a whole number
// ≥ 1 of 1/60 s substeps) and appends the positions as float32 or int16
// (MeshTopology documents the quantisation). Streams that do not ask for the
// mesh never touch any of this.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>

#include "lipsync/face/face_mesh.hpp"
#include "lipsync/face/face_rig.hpp"
#include "lipsync/face/face_solver.hpp"
#include "lipsync/model.hpp"
#include "lipsync/track.hpp"
#include "lipsync/v1/lipsync.pb.h"

namespace lipsync::server {

/// One subdivision level's mesh, its wire topology (encoding fields unset) and
/// the int16 quantisation.
struct FaceTopology {
  face::FaceMesh mesh;
  v1::MeshTopology wire;
  float scale_m = 0;
  std::array<float, 3> offset_m{};
};

/// The int16 quantisation of a rest pose: offset = centre of its bounding box,
/// scale = (largest half-extent + 0.05 m) / 32767.
void quantisation_for(const face::FaceMesh& mesh, float& scale_m, std::array<float, 3>& offset_m);
/// q = clamp(round((x − offset) / scale), ±32767).
std::int16_t quantise(double x_m, float offset_m, float scale_m);

class FaceLibrary {
 public:
  static constexpr int kMaxSubdivision = 2;

  /// The topology at `level` (0..kMaxSubdivision), built on first use. Thread-safe.
  const FaceTopology& topology(int level);
  /// The built-in rig validated against `model`, on first use. Thread-safe.
  /// Throws InputError if the model's channels cannot drive the face.
  const face::FaceRig& rig(const ArticulationModel& model);

 private:
  std::array<std::once_flag, kMaxSubdivision + 1> built_;
  std::array<std::unique_ptr<FaceTopology>, kMaxSubdivision + 1> topologies_;
  std::mutex rigs_mutex_;
  std::map<const ArticulationModel*, std::unique_ptr<face::FaceRig>> rigs_;
};

class FaceStream {
 public:
  FaceStream(const FaceTopology& topology, const face::FaceRig& rig, v1::MeshEncoding encoding);

  /// The header's topology for this stream (the shared one plus encoding and quantisation).
  v1::MeshTopology header_topology() const;
  /// Frames per FrameBatch so that a batch carries about 1 MiB of positions (1..max_frames).
  std::size_t frames_per_batch(std::size_t max_frames) const;
  /// Steps the face through frames [begin, end) of `track` and appends their positions to `batch`.
  void encode(const Track& track, std::size_t begin, std::size_t end, v1::FrameBatch& batch);

 private:
  const FaceTopology& topology_;
  face::FaceSolver solver_;
  const v1::MeshEncoding encoding_;
  std::int64_t previous_t_us_ = 0;
};

}  // namespace lipsync::server
