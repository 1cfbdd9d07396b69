// The wire's AnimationSettings onto the core's RenderSettings, plus what only
// the server resolves (plan.hpp).
#include "plan.hpp"

#include "lipsync/error.hpp"
#include "lipsync/excerpt.hpp"
#include "rpc/wire.hpp"

namespace lipsync::server {
namespace {

constexpr SettingNames kWireNames = {.fps = "settings.fps",
                                     .lookahead = "settings.lookahead",
                                     .closure_fraction = "settings.closure_fraction",
                                     .mesh_subdivision = "settings.outputs.mesh.subdivision"};

/// The engine settings the call gave (protobuf zeros and unset fields: the defaults).
RenderSettings requested_settings(const v1::AnimationSettings& settings) {
  RenderSettings requested;
  if (settings.fps() != 0) requested.fps = settings.fps();
  requested.fixed_rate = settings.fixed_rate();
  if (settings.has_lookahead()) requested.lookahead = settings.lookahead();
  if (settings.closure_fraction() != 0.0) requested.closure_fraction = settings.closure_fraction();
  if (wants_mesh(settings) && settings.outputs().mesh().has_subdivision()) {
    requested.mesh_subdivision = settings.outputs().mesh().subdivision();
  }
  return requested;
}

/// The viseme output of `settings` into `plan` (nothing unless it is enabled).
grpc::Status resolve_visemes(const v1::AnimationSettings& settings, Plan& plan) {
  const v1::VisemeOutput& output = settings.outputs().visemes();
  if (!output.enabled()) return grpc::Status::OK;
  VisemeOptions options;
  switch (output.vocabulary()) {
    case v1::VISEME_VOCABULARY_UNSPECIFIED:
    case v1::VISEME_VOCABULARY_OCULUS:
      options.vocabulary = VisemeVocabulary::oculus;
      break;
    case v1::VISEME_VOCABULARY_AZURE:
      options.vocabulary = VisemeVocabulary::azure;
      break;
    case v1::VISEME_VOCABULARY_POLLY:
      options.vocabulary = VisemeVocabulary::polly;
      break;
    case v1::VISEME_VOCABULARY_RHUBARB:
      options.vocabulary = VisemeVocabulary::rhubarb;
      break;
    default:
      return invalid("settings.outputs.visemes.vocabulary: unknown vocabulary " + std::to_string(output.vocabulary()) +
                     " (OCULUS, AZURE, POLLY or RHUBARB)");
  }
  plan.viseme_vocabulary =
      output.vocabulary() == v1::VISEME_VOCABULARY_UNSPECIFIED ? v1::VISEME_VOCABULARY_OCULUS : output.vocabulary();
  if (output.has_rhubarb_extended_shapes()) {
    const std::string& letters = output.rhubarb_extended_shapes();
    if (options.vocabulary != VisemeVocabulary::rhubarb) {
      return invalid("settings.outputs.visemes.rhubarb_extended_shapes: set for vocabulary " +
                     v1::VisemeVocabulary_Name(plan.viseme_vocabulary) + " (RHUBARB only)");
    }
    const auto shapes = rhubarb_shapes_from_string(letters);
    if (!shapes) {
      return invalid("settings.outputs.visemes.rhubarb_extended_shapes: " + excerpt(letters) +
                     " is not a set of G, H and X (e.g. GHX, GX or \"\")");
    }
    options.rhubarb_shapes = *shapes;
  }
  try {
    plan.visemes = std::make_shared<const VisemeClassifier>(*plan.model->model, options);
  } catch (const InputError& error) {
    return invalid("settings.outputs.visemes.vocabulary: " + std::string(error.what()));
  }
  return grpc::Status::OK;
}

}  // namespace

grpc::Status invalid(const std::string& message) { return {grpc::StatusCode::INVALID_ARGUMENT, message}; }

bool wants_mesh(const v1::AnimationSettings& settings) {
  return settings.outputs().has_mesh() && settings.outputs().mesh().enabled();
}

grpc::Status resolve_settings(const v1::AnimationSettings& settings, const ModelCatalog& catalog, bool with_session,
                              Plan& plan) {
  plan.model = catalog.find(settings.model());
  if (!plan.model) {
    return invalid("settings.model: unknown model " + excerpt(settings.model()) + " (known: " + catalog.names() + ")");
  }
  const std::string phone_set = settings.phone_set().empty() ? "arpabet" : settings.phone_set();
  plan.phone_set = plan.model->find_phone_set(phone_set);
  if (!plan.phone_set) {
    std::string known;
    for (const auto& set : plan.model->phone_sets) known += (known.empty() ? "" : ", ") + set.name();
    return invalid("settings.phone_set: unknown phone set " + excerpt(phone_set) + " for model '" + plan.model->name +
                   "' (known: " + known + ")");
  }
  try {
    plan.engine = resolve_render_plan(requested_settings(settings), kWireNames);
  } catch (const SettingError& error) {
    return invalid(error.what());
  }
  if (with_session && settings.session().size() > 256) {
    return invalid("settings.session: the name has " + std::to_string(settings.session().size()) +
                   " bytes, more than the 256 allowed");
  }
  const bool any = settings.outputs().channels() || settings.outputs().arkit();
  plan.channels = !any || settings.outputs().channels();
  plan.arkit = !any || settings.outputs().arkit();
  plan.mesh = wants_mesh(settings);
  plan.blinks.enabled = !settings.outputs().mesh().no_blinks();
  if (plan.mesh) {
    const v1::MeshEncoding encoding = settings.outputs().mesh().encoding();
    switch (encoding) {
      case v1::MESH_ENCODING_UNSPECIFIED:
      case v1::MESH_ENCODING_FLOAT32:
        plan.mesh_encoding = v1::MESH_ENCODING_FLOAT32;
        break;
      case v1::MESH_ENCODING_INT16:
        plan.mesh_encoding = v1::MESH_ENCODING_INT16;
        break;
      default:
        return invalid("settings.outputs.mesh.encoding: unknown encoding " + std::to_string(encoding) +
                       " (FLOAT32 or INT16)");
    }
    const v1::MeshSolve solve = settings.outputs().mesh().solve();
    switch (solve) {
      case v1::MESH_SOLVE_UNSPECIFIED:
      case v1::MESH_SOLVE_FULL:
        plan.mesh_solve = v1::MESH_SOLVE_FULL;
        break;
      case v1::MESH_SOLVE_FAST:
        plan.mesh_solve = v1::MESH_SOLVE_FAST;
        break;
      default:
        return invalid("settings.outputs.mesh.solve: unknown solve " + std::to_string(solve) + " (FULL or FAST)");
    }
  }
  if (auto status = resolve_visemes(settings, plan); !status.ok()) return status;
  plan.header = encode_header(plan, settings, with_session);
  return grpc::Status::OK;
}

grpc::Status prepare_face(Plan& plan, FaceLibrary& faces, FaceSetup& setup) {
  if (!plan.mesh) return grpc::Status::OK;
  try {
    setup.rig = &faces.rig(*plan.model->model);
  } catch (const InputError& error) {
    return invalid("settings.outputs.mesh: model '" + plan.model->name + "' cannot drive the face: " + error.what());
  }
  setup.topology = &faces.topology(plan.engine.mesh_subdivision);
  // One frame per message: a frame of positions is 5–115 kB already, and a
  // batch would hold each frame back until the solver has done the ones after it.
  setup.frames_per_batch = 1;
  *plan.header.mutable_mesh() = header_topology(*setup.topology, plan.mesh_encoding);
  plan.header.mutable_mesh()->set_solve(plan.mesh_solve);
  return grpc::Status::OK;
}

}  // namespace lipsync::server
