#include "pipeline.hpp"

#include <iostream>

#include "cli_error.hpp"
#include "files.hpp"
#include "lipsync/error.hpp"

namespace lipsync::cli {

ModelSource::ModelSource(const std::optional<std::string>& path) {
  if (!path) {
    json_text_ = std::string(ArticulationModel::builtin_json());
    return;
  }
  json_text_ = read_file(*path);
  loaded_ = ArticulationModel::from_json(json_text_, *path == "-" ? std::string(kStdinName) : *path);
}

ParseOptions parse_options_from(const Arguments& arguments) {
  ParseOptions parse_options;
  if (const auto tier = arguments.value("tier")) {
    if (tier->empty()) throw UsageError("--tier: the tier name must not be empty");
    parse_options.tier = *tier;
  }
  if (const auto rate = arguments.value("sample-rate")) {
    parse_options.timit_sample_rate_hz = parse_int_option("sample-rate", *rate, 1, 100'000'000);
  }
  return parse_options;
}

TrackFormat parse_track_format_option(std::string_view text) {
  if (const auto format = track_format_from_string(text)) return *format;
  throw UsageError("--format: unknown track format '" + std::string(text) + "' (choose " +
                   std::string(kNameList<kTrackFormats, ListStyle::choice>.view()) + ")");
}

RenderFormat parse_render_format_option(std::string_view text) {
  if (const auto format = track_format_from_string(text)) return {.track = *format, .visemes = std::nullopt};
  if (const auto format = viseme_format_from_string(text)) return {.track = std::nullopt, .visemes = *format};
  if (format_named(kMouthSwitchFormats, text)) {
    return {.track = std::nullopt, .visemes = std::nullopt, .moho_switch = true};
  }
  static constexpr auto kEveryFormat =
      kJoinedText<kNameList<kTrackFormats, ListStyle::commas>, ", ", kNameList<kVisemeFormats, ListStyle::commas>,
                  " or ", kNameList<kMouthSwitchFormats, ListStyle::choice>>;
  throw UsageError("--format: unknown format '" + std::string(text) + "' (choose " + std::string(kEveryFormat.view()) +
                   ")");
}

InputFormat parse_input_format_option(std::string_view text) {
  if (const auto format = input_format_from_string(text)) return *format;
  throw UsageError("--input-format: unknown input format '" + std::string(text) + "' (choose " +
                   std::string(kNameList<kInputFormats, ListStyle::choice>.view()) + ")");
}

bool parse_fast_mesh_solve_option(std::string_view text) {
  if (text == "fast" || text == "full") return text == "fast";
  throw UsageError("--mesh-solve: unknown solve '" + std::string(text) + "' (choose full or fast)");
}

RenderPlan parse_render_plan(const Arguments& arguments, std::optional<std::int64_t> fps_when_not_given) {
  static constexpr SettingNames kOptionNames = {.fps = "--fps",
                                                .lookahead = "--lookahead",
                                                .closure_fraction = "--closure-fraction",
                                                .mesh_subdivision = "--mesh-subdivision"};
  RenderSettings settings;
  settings.fps = fps_when_not_given;
  if (const auto text = arguments.value("fps")) settings.fps = parse_whole_option("fps", *text);
  if (const auto text = arguments.value("lookahead")) settings.lookahead = parse_whole_option("lookahead", *text);
  settings.fixed_rate = arguments.flag("fixed-rate");
  if (const auto text = arguments.value("closure-fraction")) {
    settings.closure_fraction = parse_double_option("closure-fraction", *text);
  }
  if (const auto text = arguments.value("mesh-subdivision")) {
    settings.mesh_subdivision = parse_whole_option("mesh-subdivision", *text);
  }
  try {
    return resolve_render_plan(settings, kOptionNames);
  } catch (const SettingError& error) {
    throw UsageError(error.what());
  }
}

std::string phone_set_choices() {
  std::string names;
  for (const std::string& name : PhoneSet::builtin_names()) names += name + ", ";
  return names + "auto";
}

const PhoneSet& choose_phone_set(const std::optional<std::string>& requested, const LabeledUtterance& utterance,
                                 const ArticulationModel& model, std::vector<PhoneSet>& candidates) {
  candidates.clear();
  const std::string name = requested ? *requested : utterance.phone_set;
  if (!name.empty() && name != "auto") {
    if (auto set = PhoneSet::builtin(name, model)) {
      candidates.push_back(std::move(*set));
      return candidates.front();
    }
    const std::string message = "unknown phone set '" + name + "' (choose one of: " + phone_set_choices() + ")";
    if (requested) throw UsageError("--phone-set: " + message);
    throw InputError(utterance.source, 0, "the file declares an " + message + "; override it with --phone-set");
  }
  candidates = PhoneSet::builtin_all(model);
  if (candidates.empty()) throw InputError(utterance.source, 0, "no built-in phone set to detect from");
  std::vector<std::string_view> labels;
  labels.reserve(utterance.intervals.size());
  for (const LabeledInterval& interval : utterance.intervals) labels.push_back(interval.label);
  return detect_phone_set(candidates, labels);
}

Track render_utterance(const LabeledUtterance& utterance, const ArticulationModel& model, const PhoneSet& phone_set,
                       const TrackRequest& request) {
  if (!request.incremental) {
    return render_track(model, build_segments(utterance, model, phone_set, request.segments), request.render);
  }
  if (utterance.intervals.empty()) throw InputError(utterance.source, 0, "the utterance has no phonemes");
  SegmentBuilder builder(model, phone_set, utterance.source, request.segments);
  StreamingRenderer renderer(model, request.render);
  Track track;
  track.channel_count = model.channel_count();
  track.fps = request.render.fps;
  std::vector<Segment> segments;
  for (const LabeledInterval& interval : utterance.intervals) {
    segments.clear();
    builder.push(interval, segments);
    for (const Segment& segment : segments) renderer.push(segment, track);
  }
  renderer.finish(track);
  return track;
}

void write_output(const Track& track, const ArticulationModel& model, TrackFormat format, const std::string& output) {
  write_to_output(output, "track", [&](std::ostream& out) { write_track(track, model, format, out); });
}

void write_viseme_output(const Track& track, const ArticulationModel& model, const VisemeOptions& options,
                         VisemeFormat format, std::int64_t end_us, const std::string& output) {
  const VisemeClassifier classifier(model, options);
  const VisemeTrack visemes = compute_visemes(classifier, track);
  const VisemeTrackView view{
      .model = model.name(), .classifier = classifier, .track = track, .visemes = visemes, .end_us = end_us};
  write_to_output(output, "visemes", [&](std::ostream& out) { write_visemes(view, format, out); });
}

void write_moho_output(const Track& track, const ArticulationModel& model, const VisemeOptions& options, int fps,
                       std::int64_t end_us, const std::string& output) {
  const VisemeClassifier classifier(model, options);
  const VisemeTrack visemes = compute_visemes(classifier, track);
  const VisemeTrackView view{
      .model = model.name(), .classifier = classifier, .track = track, .visemes = visemes, .end_us = end_us};
  write_to_output(output, "switch data", [&](std::ostream& out) { write_moho_switch(view, fps, out); });
}

}  // namespace lipsync::cli
