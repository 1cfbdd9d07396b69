// Settings to plan: the AnimationSettings of a call resolved, once, into what
// the call runs (model, phone set, engine options, outputs, the track header).
//
// The ranges and defaults of the engine settings are the core's
// (lipsync/render_plan.hpp); this file maps the wire's fields onto them (a zero
// fps or closure fraction and an unset lookahead or subdivision mean "the
// default"), checks what only the server knows (model and phone set names, the
// session name, the mesh encoding, the viseme vocabulary) and turns every
// error into INVALID_ARGUMENT
// naming the field, e.g. "settings.fps: '241' is out of range (1 to 240, default 30)".
#pragma once

#include <grpcpp/support/status.h>

#include <cstddef>
#include <memory>
#include <string>

#include "catalog.hpp"
#include "face/face_stream.hpp"
#include "lipsync/render_plan.hpp"
#include "lipsync/v1/lipsync.pb.h"
#include "lipsync/visemes.hpp"

namespace lipsync::server {

/// Frames per FrameBatch when the mesh is not asked for.
inline constexpr std::size_t kMaxFramesPerBatch = 512;

struct Plan {
  const ModelEntry* model = nullptr;
  const PhoneSet* phone_set = nullptr;
  RenderPlan engine;  ///< fps, lookahead, closure fraction, mesh subdivision (validated by the core)
  bool channels = true;
  bool arkit = true;
  bool mesh = false;
  v1::MeshEncoding mesh_encoding = v1::MESH_ENCODING_FLOAT32;
  v1::MeshSolve mesh_solve = v1::MESH_SOLVE_FULL;  ///< FULL or FAST (settings.outputs.mesh.solve)
  face::BlinkSettings blinks;                      ///< settings.outputs.mesh.no_blinks turns them off
  /// The viseme output's classifier (null unless asked for); each stream brings its own event detector.
  std::shared_ptr<const VisemeClassifier> visemes;
  v1::VisemeVocabulary viseme_vocabulary = v1::VISEME_VOCABULARY_UNSPECIFIED;
  v1::TrackHeader header;
};

grpc::Status invalid(const std::string& message);

/// Whether the settings ask for the mesh output.
bool wants_mesh(const v1::AnimationSettings& settings);

/// Resolves `settings` into `plan` (and its header); INVALID_ARGUMENT naming
/// the field otherwise. `with_session`: the call may name a session (Animate).
grpc::Status resolve_settings(const v1::AnimationSettings& settings, const ModelCatalog& catalog, bool with_session,
                              Plan& plan);

/// What a stream's face needs (its solver is built later, off the reaction:
/// see FaceWorkers), with the topology put in the plan's header.
struct FaceSetup {
  const FaceTopology* topology = nullptr;
  const face::FaceRig* rig = nullptr;
  std::size_t frames_per_batch = kMaxFramesPerBatch;
};

/// The face of a plan that asks for the mesh (nothing otherwise). INVALID_ARGUMENT
/// if the model cannot drive it.
grpc::Status prepare_face(Plan& plan, FaceLibrary& faces, FaceSetup& setup);

}  // namespace lipsync::server
