// Parsing and validation of the muscle rig (data/face/rig.json); format in docs/face.md.
#include "lipsync/face/face_rig.hpp"

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>
#include <numbers>
#include <set>

#include "face/embedded_face.hpp"
#include "lipsync/error.hpp"

namespace lipsync::face {

namespace {

constexpr std::uint32_t kLandmarkCount = 468;

class RigReader {
 public:
  explicit RigReader(std::string_view source) : source_(source) {}

  [[noreturn]] void fail(const std::string& where, const std::string& what) const {
    throw InputError(source_, 0, where + ": " + what);
  }

  const nlohmann::json& field(const nlohmann::json& object, const char* name, const std::string& where) const {
    if (!object.is_object() || !object.contains(name)) fail(where, std::string("missing field '") + name + "'");
    return object.at(name);
  }

  double number(const nlohmann::json& object, const char* name, const std::string& where, double min, double max,
                std::optional<double> fallback = std::nullopt) const {
    if (fallback && (!object.is_object() || !object.contains(name))) return *fallback;
    const auto& value = field(object, name, where);
    if (!value.is_number()) fail(where, std::string("field '") + name + "' must be a number");
    const double v = value.get<double>();
    if (!(v >= min && v <= max))
      fail(where, std::string("field '") + name + "' = " + std::to_string(v) + " is outside [" + std::to_string(min) +
                      ", " + std::to_string(max) + "]");
    return v;
  }

  std::string text(const nlohmann::json& object, const char* name, const std::string& where) const {
    const auto& value = field(object, name, where);
    if (!value.is_string()) fail(where, std::string("field '") + name + "' must be a string");
    return value.get<std::string>();
  }

  std::size_t channel(const ArticulationModel& model, const std::string& name, const std::string& kind,
                      const std::string& where) const {
    const auto& channels = model.channels();
    for (std::size_t i = 0; i < channels.size(); ++i)
      if (channels[i].name == name) {
        if (channels[i].kind != kind)
          fail(where, "channel '" + name + "' is of kind '" + channels[i].kind + "', not '" + kind + "'");
        return i;
      }
    fail(where, "channel '" + name + "' is not in model '" + model.name() + "'");
  }

 private:
  std::string source_;
};

}  // namespace

FaceRig FaceRig::from_json(std::string_view json_text, std::string_view source, const ArticulationModel& model) {
  const RigReader in(source);
  nlohmann::json doc;
  try {
    doc = nlohmann::json::parse(json_text);
  } catch (const nlohmann::json::exception& e) {  // parse_error, and out_of_range for a number that overflows
    in.fail("rig", std::string("not valid JSON: ") + e.what());
  }
  if (in.text(doc, "format", "rig") != "lipsync-face-rig") in.fail("rig", "field 'format' must be lipsync-face-rig");
  FaceRig rig;
  rig.channel_count_ = model.channel_count();

  const auto& jaw = in.field(doc, "jaw", "rig");
  rig.jaw_channel_ = in.channel(model, in.text(jaw, "channel", "jaw"), "jaw", "jaw");
  rig.max_jaw_rotation_rad_ = in.number(jaw, "max_rotation_deg", "jaw", 1.0, 45.0) * std::numbers::pi / 180.0;
  rig.jaw_seal_below_ = in.number(jaw, "seal_below", "jaw", 0.0, 0.5, 0.0);
  rig.jaw_seal_release_ = in.number(jaw, "seal_release", "jaw", 0.0, 0.5, rig.jaw_seal_below_);
  if (rig.jaw_seal_release_ < rig.jaw_seal_below_)
    in.fail("jaw", "field 'seal_release' must not be below field 'seal_below'");
  const auto& tongue = in.field(doc, "tongue", "rig");
  rig.tongue_raise_channel_ = in.channel(model, in.text(tongue, "raise_channel", "tongue"), "tongue", "tongue");
  rig.max_tongue_raise_rad_ = in.number(tongue, "max_raise_deg", "tongue", 0.0, 45.0) * std::numbers::pi / 180.0;
  rig.tongue_protrusion_channel_ =
      in.channel(model, in.text(tongue, "protrusion_channel", "tongue"), "tongue", "tongue");
  rig.max_tongue_protrusion_m_ = in.number(tongue, "max_protrusion_m", "tongue", 0.0, 0.05);

  const auto& muscles = in.field(doc, "muscles", "rig");
  if (!muscles.is_array()) in.fail("rig", "field 'muscles' must be an array");
  std::set<std::string> seen;
  for (std::size_t m = 0; m < muscles.size(); ++m) {
    const auto& json = muscles[m];
    MuscleSpec spec;
    spec.name = in.text(json, "name", "muscle " + std::to_string(m));
    const std::string where = "muscle '" + spec.name + "'";
    if (!seen.insert(spec.name).second) in.fail(where, "appears twice");
    spec.channel = in.channel(model, spec.name, "muscle", where);
    const std::string kind = in.text(json, "kind", where);
    if (kind == "linear")
      spec.kind = MuscleKind::linear;
    else if (kind == "sphincter")
      spec.kind = MuscleKind::sphincter;
    else
      in.fail(where, "field 'kind' = '" + kind + "' must be 'linear' or 'sphincter'");
    const std::string bone = in.text(json, "bone", where);
    if (bone == "skull")
      spec.bone = Bone::skull;
    else if (bone == "jaw")
      spec.bone = Bone::jaw;
    else
      in.fail(where, "field 'bone' = '" + bone + "' must be 'skull' or 'jaw'");
    const auto& fibres = in.field(json, "fibres", where);
    if (!fibres.is_array() || fibres.empty()) in.fail(where, "field 'fibres' must be a non-empty array");
    for (std::size_t f = 0; f < fibres.size(); ++f) {
      const std::string fibre_where = where + " fibre " + std::to_string(f);
      FibreSpec fibre;
      const auto& path = in.field(fibres[f], "path", fibre_where);
      if (!path.is_array() || path.size() < 2) in.fail(fibre_where, "field 'path' must list at least 2 landmark ids");
      for (const auto& id : path) {
        if (!id.is_number_integer() || id.get<long long>() < 0 || id.get<long long>() >= kLandmarkCount)
          in.fail(fibre_where, "field 'path' has " + id.dump() + ", not a landmark id in [0, 467]");
        fibre.path.push_back(id.get<std::uint32_t>());
      }
      fibre.radius_m = in.number(fibres[f], "radius_m", fibre_where, 0.001, 0.05);
      spec.fibres.push_back(std::move(fibre));
    }
    if (spec.kind == MuscleKind::linear) {
      spec.max_shortening_m = in.number(json, "max_shortening_m", where, 0.0, 0.05);
      spec.mobile_from = in.number(json, "mobile_from", where, -1.0, 0.99, 0.0);
      spec.bulge_m = in.number(json, "bulge_m", where, 0.0, 0.02, 0.0);
      spec.origin_depth_m = in.number(json, "origin_depth_m", where, 0.0, 0.05, 0.0);
    } else {
      spec.closure_m = in.number(json, "closure_m", where, 0.0, 0.05);
      spec.closure_saturation = in.number(json, "closure_saturation", where, 0.01, 1.0, 1.0);
      const auto& dir = in.field(json, "closure_direction", where);
      if (!dir.is_array() || dir.size() != 3 || !dir[0].is_number() || !dir[1].is_number() || !dir[2].is_number())
        in.fail(where, "field 'closure_direction' must be [x, y, z]");
      Vec3 d{dir[0].get<double>(), dir[1].get<double>(), dir[2].get<double>()};
      const double length = std::sqrt(d.x * d.x + d.y * d.y + d.z * d.z);
      if (!(length > 0)) in.fail(where, "field 'closure_direction' must not be zero");
      spec.closure_direction = {d.x / length, d.y / length, d.z / length};
      spec.purse = in.number(json, "purse", where, 0.0, 1.0, 0.0);
      spec.protrusion_m = in.number(json, "protrusion_m", where, -0.02, 0.02, 0.0);
      spec.eversion_m = in.number(json, "eversion_m", where, 0.0, 0.02, 0.0);
      if (json.contains("jaw_compensation")) {
        const std::string comp_where = where + " jaw_compensation";
        const auto& comp = json["jaw_compensation"];
        if (spec.bone != Bone::jaw) in.fail(where, "field 'jaw_compensation' needs 'bone' = 'jaw'");
        spec.compensation_channel = in.channel(model, in.text(comp, "driver", comp_where), "muscle", comp_where);
        spec.compensation_from = in.number(comp, "from", comp_where, 0.0, 1.0);
        spec.compensation_full = in.number(comp, "full", comp_where, 0.0, 1.0);
        if (!(spec.compensation_full > spec.compensation_from))
          in.fail(comp_where, "field 'full' must be greater than field 'from'");
        spec.compensation_share = in.number(comp, "share", comp_where, 0.0, 1.0);
      }
    }
    rig.muscles_.push_back(std::move(spec));
  }
  for (const auto& channel : model.channels())
    if (channel.kind == "muscle" && !seen.count(channel.name))
      in.fail("muscle '" + channel.name + "'", "channel of model '" + model.name() + "' has no muscle in the rig");
  std::sort(rig.muscles_.begin(), rig.muscles_.end(),
            [](const MuscleSpec& a, const MuscleSpec& b) { return a.channel < b.channel; });
  return rig;
}

std::string_view FaceRig::builtin_json() { return embedded::face_rig_json(); }

double FaceRig::skin_jaw_value(double jaw) const {
  if (jaw >= jaw_seal_release_) return jaw;
  if (jaw <= jaw_seal_below_) return 0.0;
  const double t = (jaw - jaw_seal_below_) / (jaw_seal_release_ - jaw_seal_below_);
  return jaw * t * t * (3.0 - 2.0 * t);
}

const FaceRig& FaceRig::builtin() {
  static const FaceRig kRig = from_json(builtin_json(), "data/face/kRig.json", ArticulationModel::builtin());
  return kRig;
}

}  // namespace lipsync::face
