// The mesh output: the physics face (lipsync::face, docs/face.md) driven by a
// stream's frames.
//
// FaceLibrary holds what every stream shares: the FaceMesh and its wire
// topology per subdivision level (built on first use, once, under a
// std::once_flag per level), the FaceRig validated per model, and a pool of
// solvers at rest per level, rig and solve (FULL or FAST:
// settings.outputs.mesh.solve), so that a stream (one utterance) does not pay
// for binding and factoring a new one. A FaceStream is one stream's FaceSolver
// (its own state: the face moves with that stream only); it steps once per
// released frame with dt = t_i − t_{i−1} (t_{−1} = 0: key frames make the steps
// uneven; FaceSolver simulates each dt exactly, in substeps of at most its
// 1/30 s step), by face::FaceTrackStepper, the rule `lipsync render
// --mesh/--video` follows too (one face per input), and appends the positions
// as float32 or int16 (MeshTopology documents the quantisation). It runs on the face threads
// (face_workers.hpp). Streams that do not ask for the mesh never touch any of this.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <tuple>
#include <utility>
#include <vector>

#include "lipsync/face/face_animation.hpp"
#include "lipsync/face/face_mesh.hpp"
#include "lipsync/face/face_rig.hpp"
#include "lipsync/face/face_solver.hpp"
#include "lipsync/model.hpp"
#include "lipsync/setting_ranges.hpp"
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
  struct SolverReturn;

 public:
  static constexpr int kMaxSubdivision = static_cast<int>(kMeshSubdivisionSetting.max);
  /// Solvers at rest kept per (level, rig, solve) for the next stream.
  static constexpr std::size_t kPooledSolvers = 16;

  /// A solver at rest on its way back to the pool when released.
  using PooledSolver = std::unique_ptr<face::FaceSolver, SolverReturn>;

  /// The topology at `level` (0..kMaxSubdivision), built on first use. Thread-safe.
  const FaceTopology& topology(int level);
  /// The built-in rig validated against `model`, on first use. Thread-safe.
  /// Throws InputError if the model's channels cannot drive the face.
  const face::FaceRig& rig(const ArticulationModel& model);
  /// A solver for `topology` driven by `rig` with `solve`'s parameters (FAST:
  /// face::fast_face_solver_params(); anything else the defaults), at rest: one a
  /// finished stream gave back (reset, so it computes exactly what a new one
  /// would), else a new one (binding and factoring: tens of milliseconds at
  /// level 1). Thread-safe. The library must outlive it.
  PooledSolver solver(const FaceTopology& topology, const face::FaceRig& rig,
                      v1::MeshSolve solve = v1::MESH_SOLVE_FULL);

 private:
  struct SolverReturn {
    FaceLibrary* library = nullptr;
    const FaceTopology* topology = nullptr;
    const face::FaceRig* rig = nullptr;
    bool fast = false;
    void operator()(face::FaceSolver* solver) const;
  };
  using PoolKey = std::tuple<const FaceTopology*, const face::FaceRig*, bool>;  // bool: FAST

  std::array<std::once_flag, kMaxSubdivision + 1> built_;
  std::array<std::unique_ptr<FaceTopology>, kMaxSubdivision + 1> topologies_;
  std::mutex rigs_mutex_;
  std::map<const ArticulationModel*, std::unique_ptr<face::FaceRig>> rigs_;
  std::mutex pool_mutex_;
  std::map<PoolKey, std::vector<std::unique_ptr<face::FaceSolver>>> pool_;
};

/// The header's topology for a stream with `encoding` (the shared one plus encoding and quantisation).
v1::MeshTopology header_topology(const FaceTopology& topology, v1::MeshEncoding encoding);

class FaceStream {
 public:
  /// `blinks`: the eyelids' schedule (settings.outputs.mesh.no_blinks turns it off).
  FaceStream(const FaceTopology& topology, FaceLibrary::PooledSolver solver, v1::MeshEncoding encoding,
             face::BlinkSettings blinks = {});

  /// Steps the face through frames [begin, end) of `track` and appends their positions to `batch`.
  void encode(const Track& track, std::size_t begin, std::size_t end, v1::FrameBatch& batch);

 private:
  const FaceTopology& topology_;
  FaceLibrary::PooledSolver solver_;
  const v1::MeshEncoding encoding_;
  face::FaceTrackStepper stepper_;
};

}  // namespace lipsync::server
