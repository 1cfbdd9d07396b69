#include "face_stream.hpp"

#include <algorithm>
#include <cmath>

namespace lipsync::server {
namespace {

v1::MeshPart to_proto(face::FacePart part) {
  switch (part) {
    case face::FacePart::skin:
      return v1::MESH_PART_SKIN;
    case face::FacePart::inner_lip:
      return v1::MESH_PART_INNER_LIP;
    case face::FacePart::mouth_cavity:
      return v1::MESH_PART_MOUTH_CAVITY;
    case face::FacePart::upper_teeth:
      return v1::MESH_PART_UPPER_TEETH;
    case face::FacePart::lower_teeth:
      return v1::MESH_PART_LOWER_TEETH;
    case face::FacePart::tongue:
      return v1::MESH_PART_TONGUE;
    case face::FacePart::eye_white:
      return v1::MESH_PART_EYE_WHITE;
    case face::FacePart::iris:
      return v1::MESH_PART_IRIS;
    case face::FacePart::pupil:
      return v1::MESH_PART_PUPIL;
  }
  return v1::MESH_PART_SKIN;
}

std::unique_ptr<FaceTopology> build_topology(int level) {
  auto topology = std::make_unique<FaceTopology>();
  topology->mesh = face::build_face_mesh(face::FaceAsset::builtin(), level);
  const face::FaceMesh& mesh = topology->mesh;
  v1::MeshTopology& wire = topology->wire;
  wire.set_subdivision(static_cast<std::uint32_t>(level));
  wire.set_vertex_count(static_cast<std::uint32_t>(mesh.vertex_count()));
  wire.set_soft_vertex_count(mesh.soft_node_count);
  wire.set_units("m");
  wire.mutable_rest_positions()->Reserve(static_cast<int>(mesh.vertex_count() * 3));
  for (const face::Vec3& p : mesh.rest_positions_m) {
    wire.add_rest_positions(static_cast<float>(p.x));
    wire.add_rest_positions(static_cast<float>(p.y));
    wire.add_rest_positions(static_cast<float>(p.z));
  }
  wire.mutable_triangles()->Reserve(static_cast<int>(mesh.triangles.size() * 3));
  for (const auto& triangle : mesh.triangles) {
    for (const std::uint32_t vertex : triangle) wire.add_triangles(vertex);
  }
  wire.mutable_uvs()->Reserve(static_cast<int>(mesh.uvs.size() * 2));
  for (const auto& uv : mesh.uvs) {
    wire.add_uvs(uv[0]);
    wire.add_uvs(uv[1]);
  }
  for (const face::FacePart part : mesh.parts) wire.add_parts(to_proto(part));
  quantisation_for(mesh, topology->scale_m, topology->offset_m);
  return topology;
}

}  // namespace

void quantisation_for(const face::FaceMesh& mesh, float& scale_m, std::array<float, 3>& offset_m) {
  std::array<double, 3> low{HUGE_VAL, HUGE_VAL, HUGE_VAL}, high{-HUGE_VAL, -HUGE_VAL, -HUGE_VAL};
  for (const face::Vec3& p : mesh.rest_positions_m) {
    const std::array<double, 3> xyz{p.x, p.y, p.z};
    for (int axis = 0; axis < 3; ++axis) {
      low[axis] = std::min(low[axis], xyz[axis]);
      high[axis] = std::max(high[axis], xyz[axis]);
    }
  }
  double half = 0;
  for (int axis = 0; axis < 3; ++axis) {
    offset_m[axis] = static_cast<float>((low[axis] + high[axis]) / 2);
    half = std::max(half, (high[axis] - low[axis]) / 2);
  }
  scale_m = static_cast<float>((half + 0.05) / 32767.0);
}

std::int16_t quantise(double x_m, float offset_m, float scale_m) {
  const double q = std::nearbyint((x_m - static_cast<double>(offset_m)) / static_cast<double>(scale_m));
  return static_cast<std::int16_t>(std::clamp(q, -32767.0, 32767.0));
}

const FaceTopology& FaceLibrary::topology(int level) {
  const auto index = static_cast<std::size_t>(level);
  std::call_once(built_.at(index), [&] { topologies_[index] = build_topology(level); });
  return *topologies_[index];
}

const face::FaceRig& FaceLibrary::rig(const ArticulationModel& model) {
  if (&model == &ArticulationModel::builtin()) return face::FaceRig::builtin();
  std::lock_guard lock(rigs_mutex_);
  auto& rig = rigs_[&model];
  if (!rig) {
    rig = std::make_unique<face::FaceRig>(
        face::FaceRig::from_json(face::FaceRig::builtin_json(), "data/face/rig.json", model));
  }
  return *rig;
}

FaceLibrary::PooledSolver FaceLibrary::solver(const FaceTopology& topology, const face::FaceRig& rig,
                                              v1::MeshSolve solve) {
  const bool fast = solve == v1::MESH_SOLVE_FAST;
  SolverReturn give_back{this, &topology, &rig, fast};
  {
    std::lock_guard lock(pool_mutex_);
    auto& pooled = pool_[{&topology, &rig, fast}];
    if (!pooled.empty()) {
      PooledSolver solver(pooled.back().release(), give_back);
      pooled.pop_back();
      return solver;
    }
  }
  return PooledSolver(
      new face::FaceSolver(topology.mesh, rig, fast ? face::fast_face_solver_params() : face::FaceSolverParams{}),
      give_back);
}

void FaceLibrary::SolverReturn::operator()(face::FaceSolver* solver) const {
  std::unique_ptr<face::FaceSolver> owned(solver);
  owned->reset();
  std::lock_guard lock(library->pool_mutex_);
  auto& pooled = library->pool_[{topology, rig, fast}];
  if (pooled.size() < kPooledSolvers) pooled.push_back(std::move(owned));
}

FaceStream::FaceStream(const FaceTopology& topology, FaceLibrary::PooledSolver solver, v1::MeshEncoding encoding,
                       face::BlinkSettings blinks)
    : topology_(topology), solver_(std::move(solver)), encoding_(encoding), stepper_(*solver_, blinks) {}

v1::MeshTopology header_topology(const FaceTopology& topology, v1::MeshEncoding encoding) {
  v1::MeshTopology wire = topology.wire;
  wire.set_encoding(encoding);
  if (encoding == v1::MESH_ENCODING_INT16) {
    wire.set_quantisation_scale_m(topology.scale_m);
    for (const float offset : topology.offset_m) wire.add_quantisation_offset_m(offset);
  }
  return wire;
}

void FaceStream::encode(const Track& track, std::size_t begin, std::size_t end, v1::FrameBatch& batch) {
  const std::size_t vertices = topology_.mesh.vertex_count();
  const std::size_t count = end - begin;
  const bool int16 = encoding_ == v1::MESH_ENCODING_INT16;
  std::string* bytes = int16 ? batch.mutable_mesh_positions_int16() : nullptr;
  if (int16) {
    bytes->reserve(bytes->size() + count * vertices * 6);
  } else {
    batch.mutable_mesh_positions()->Reserve(batch.mesh_positions_size() + static_cast<int>(count * vertices * 3));
  }
  for (std::size_t frame = begin; frame < end; ++frame) {
    for (const face::Vec3& p : stepper_.step(track.t_us[frame], track.frame_values(frame))) {
      const std::array<double, 3> xyz{p.x, p.y, p.z};
      for (int axis = 0; axis < 3; ++axis) {
        if (int16) {
          const auto q = static_cast<std::uint16_t>(quantise(xyz[axis], topology_.offset_m[axis], topology_.scale_m));
          bytes->push_back(static_cast<char>(q & 0xff));
          bytes->push_back(static_cast<char>(q >> 8));
        } else {
          batch.add_mesh_positions(static_cast<float>(xyz[axis]));
        }
      }
    }
  }
}

}  // namespace lipsync::server
