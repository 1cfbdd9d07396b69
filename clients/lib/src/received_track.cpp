// The tracks as the client receives them: ReceivedTrack gathers a stream's header, frame
// batches (channel values, ARKit weights, visemes, the mesh with int16 batches decoded) and
// summary into a core Track, SpokenTrack a Speak stream's audio beside its track; both check
// every message against the protocol and throw CallError (INTERNAL) where the server breaks it.
// Also the conversions of a frame kind and a phoneme between the core and the wire.
#include <algorithm>

#include "call_context.hpp"
#include "lipsync/client/animation_client.hpp"

namespace lipsync::client {

using detail::protocol_error;

FrameKind to_core(v1::FrameKind kind) {
  switch (kind) {
    case v1::FRAME_KIND_CLOSURE_START:
      return FrameKind::closure_start;
    case v1::FRAME_KIND_CLOSURE_END:
      return FrameKind::closure_end;
    case v1::FRAME_KIND_SHORT_SEGMENT:
      return FrameKind::short_segment;
    default:
      return FrameKind::uniform;
  }
}

v1::Phoneme to_wire(const LabeledInterval& interval) {
  v1::Phoneme phoneme;
  phoneme.set_label(interval.label);
  phoneme.set_start_us(interval.start_us);
  phoneme.set_end_us(interval.end_us);
  return phoneme;
}

void ReceivedTrack::add(const v1::TrackMessage& message) {
  switch (message.kind_case()) {
    case v1::TrackMessage::kHeader:
      header = message.header();
      track = Track{};
      track.channel_count = static_cast<std::size_t>(header.channels_size());
      track.fps = static_cast<int>(header.fps());
      arkit.clear();
      mesh_positions.clear();
      viseme_weights.clear();
      viseme_events.clear();
      first_frame = 0;
      break;
    case v1::TrackMessage::kFrames:
      add_frames(message.frames());
      break;
    case v1::TrackMessage::kSummary:
      summary = message.summary();
      break;
    default:
      throw protocol_error("a stream message with no content");
  }
}

void ReceivedTrack::add_frames(const v1::FrameBatch& batch) {
  if (header.fps() == 0) throw protocol_error("frames arrived before the track header");
  const auto frames = static_cast<std::size_t>(batch.t_us_size());
  const auto arkit_count = static_cast<std::size_t>(header.arkit_names_size());
  if (track.t_us.empty()) first_frame = batch.first_frame();
  if (batch.first_frame() != first_frame + track.frame_count()) {
    throw protocol_error("frame batch starts at frame " + std::to_string(batch.first_frame()) + ", expected " +
                         std::to_string(first_frame + track.frame_count()));
  }
  const std::size_t mesh_count = header.has_mesh() ? std::size_t{header.mesh().vertex_count()} * 3 : 0;
  const bool int16 = header.has_mesh() && header.mesh().encoding() == v1::MESH_ENCODING_INT16;
  if (int16 && header.mesh().quantisation_offset_m_size() != 3) {
    throw protocol_error("the mesh topology has no int16 quantisation offset");
  }
  if (static_cast<std::size_t>(batch.values_size()) != frames * track.channel_count ||
      static_cast<std::size_t>(batch.arkit_size()) != frames * arkit_count ||
      static_cast<std::size_t>(batch.viseme_weights_size()) !=
          frames * static_cast<std::size_t>(header.viseme_names_size()) ||
      static_cast<std::size_t>(batch.mesh_positions_size()) != (int16 ? 0 : frames * mesh_count) ||
      batch.mesh_positions_int16().size() != (int16 ? frames * mesh_count * 2 : 0) ||
      (batch.kinds_size() != 0 && static_cast<std::size_t>(batch.kinds_size()) != frames)) {
    throw protocol_error("frame batch at frame " + std::to_string(batch.first_frame()) +
                         " has sizes that do not match its " + std::to_string(frames) + " frames");
  }
  for (const v1::VisemeEvent& event : batch.viseme_events()) {
    if (event.viseme() >= static_cast<std::uint32_t>(header.viseme_names_size()) ||
        std::find(batch.t_us().begin(), batch.t_us().end(), event.start_us()) == batch.t_us().end()) {
      throw protocol_error("frame batch at frame " + std::to_string(batch.first_frame()) + " has a viseme event (" +
                           std::to_string(event.viseme()) + " at " + std::to_string(event.start_us()) +
                           " us) that names no viseme or starts at none of its frames");
    }
  }
  for (std::size_t i = 0; i < frames; ++i) {
    const std::int64_t t_us = batch.t_us(static_cast<int>(i));
    if (!track.t_us.empty() && t_us <= track.t_us.back()) {
      throw protocol_error("frame times do not increase at frame " + std::to_string(track.frame_count()));
    }
    track.t_us.push_back(t_us);
    track.kinds.push_back(batch.kinds_size() == 0 ? FrameKind::uniform : to_core(batch.kinds(static_cast<int>(i))));
  }
  track.values.insert(track.values.end(), batch.values().begin(), batch.values().end());
  arkit.insert(arkit.end(), batch.arkit().begin(), batch.arkit().end());
  viseme_weights.insert(viseme_weights.end(), batch.viseme_weights().begin(), batch.viseme_weights().end());
  for (const v1::VisemeEvent& event : batch.viseme_events()) {
    viseme_events.push_back({.viseme = event.viseme(), .start_us = event.start_us()});
  }
  mesh_positions.insert(mesh_positions.end(), batch.mesh_positions().begin(), batch.mesh_positions().end());
  if (int16) {
    const std::string& bytes = batch.mesh_positions_int16();
    const double scale = header.mesh().quantisation_scale_m();
    for (std::size_t i = 0; i + 1 < bytes.size(); i += 2) {
      const auto q = static_cast<std::int16_t>(
          static_cast<std::uint16_t>(static_cast<unsigned>(static_cast<std::uint8_t>(bytes[i])) |
                                     (static_cast<unsigned>(static_cast<std::uint8_t>(bytes[i + 1])) << 8)));
      const double offset = header.mesh().quantisation_offset_m(static_cast<int>((i / 2) % 3));
      mesh_positions.push_back(static_cast<float>(offset + scale * q));
    }
  }
}

void SpokenTrack::add(const v1::SpeakResponse& message) {
  const bool started = header.sample_rate_hz() != 0;
  if (!started && !message.has_header()) throw protocol_error("a Speak message before the SpeakHeader");
  switch (message.kind_case()) {
    case v1::SpeakResponse::kHeader: {
      if (started) throw protocol_error("a second SpeakHeader");
      if (message.header().sample_rate_hz() == 0 || message.header().channels() != 1 ||
          message.header().sample_format() != v1::SAMPLE_FORMAT_PCM_S16LE) {
        throw protocol_error("a SpeakHeader with an audio format other than mono PCM_S16LE at a known rate");
      }
      header = message.header();
      samples.clear();
      samples.reserve(header.sample_count());
      v1::TrackMessage track_header;
      *track_header.mutable_header() = header.track();
      track.add(track_header);
      break;
    }
    case v1::SpeakResponse::kAudio: {
      const v1::AudioChunk& chunk = message.audio();
      const std::string& pcm = chunk.pcm();
      if (chunk.first_sample() != samples.size()) {
        throw protocol_error("an audio chunk starting at sample " + std::to_string(chunk.first_sample()) + " after " +
                             std::to_string(samples.size()) + " samples");
      }
      if (pcm.size() % 2 != 0 || samples.size() + pcm.size() / 2 > header.sample_count()) {
        throw protocol_error("an audio chunk of " + std::to_string(pcm.size()) + " bytes at sample " +
                             std::to_string(samples.size()) + " of " + std::to_string(header.sample_count()));
      }
      for (std::size_t i = 0; i < pcm.size(); i += 2) {
        const auto low = static_cast<std::uint8_t>(pcm[i]);
        const auto high = static_cast<std::uint8_t>(pcm[i + 1]);
        samples.push_back(static_cast<std::int16_t>(static_cast<std::uint16_t>(low | (high << 8))));
      }
      break;
    }
    case v1::SpeakResponse::kFrames:
      track.add_frames(message.frames());
      break;
    case v1::SpeakResponse::kSummary:
      summary = message.summary();
      track.summary = message.summary().track();
      break;
    default:
      throw protocol_error("a Speak message with no content");
  }
}

}  // namespace lipsync::client
