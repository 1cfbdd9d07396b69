// The byte format of fuzz_animate_stream's inputs: a small program of client
// actions on up to two Animate streams and two Subscribe streams of one
// server, decoded front to back (ProgramReader) and written by the seed
// generator (ProgramWriter), so that seeds and fuzzer read the same bytes.
//
// Random bytes alone mostly die in protobuf parsing before they reach the
// streaming code; a program keeps the messages well formed (the mutations
// change values, not framing) and mixes in what only a client's timing can
// do: half-closing early, cancelling, subscribing while the producer runs,
// and raw bytes that need not be an AnimateRequest at all.
//
// Each action is one byte, `slot << 4 | op` (slot 0 or 1; the high bits are
// ignored, and an op beyond Op::count is skipped), followed by its operands:
//   open        u8 Metadata (explicit_value: then a string): opens Animate stream `slot`
//   settings    SettingsBits, then the fields they select, in the order of the bits
//   phonemes    u8 count, then per phoneme: string label, u8 timing, then
//               timing even: varint gap_us, varint duration_us after the previous end;
//               timing odd: i64 start_us, i64 end_us (anything, to break the order)
//   end         -
//   raw         string: sent as the message's bytes as they are
//   half_close  -                             WritesDone
//   cancel      -                             the client cancels the call
//   subscribe   string session, u8 start, metadata: opens Subscribe stream `slot`
//   cancel_subscriber -
// An Animate stream that a settings, phonemes, end or raw action names before
// any open is opened without metadata. Strings are a u8 length (255: a u16
// length follows) and the bytes; integers are little-endian; the reader gives
// zeros past the end.
#pragma once

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>

namespace lipsync::fuzz {

enum class Op : std::uint8_t {
  open,
  settings,
  phonemes,
  end,
  raw,
  half_close,
  cancel,
  subscribe,
  cancel_subscriber,
  count
};

/// The x-lipsync-session metadata of a call: none, the session name the
/// action sends in the body, or the string that follows.
enum class Metadata : std::uint8_t { none, same_as_body, explicit_value };

/// Which AnimationSettings fields a settings action sets (the rest stay unset).
enum SettingsBits : std::uint16_t {
  kModel = 1 << 0,            // string
  kFps = 1 << 1,              // u16
  kPhoneSet = 1 << 2,         // string
  kLookahead = 1 << 3,        // u8
  kFixedRate = 1 << 4,        // -
  kClosureFraction = 1 << 5,  // f64
  kSession = 1 << 6,          // string
  kMediaClock = 1 << 7,       // string clock, i64 utterance_zero_us
  kChannels = 1 << 8,         // -
  kArkit = 1 << 9,            // -
  kVisemes = 1 << 10,         // u8 vocabulary
  kRhubarbShapes = 1 << 11,   // string
  kMesh = 1 << 12,            // u8 subdivision, u8 encoding
};

class ProgramReader {
 public:
  explicit ProgramReader(std::string_view bytes) : bytes_(bytes) {}

  bool done() const { return position_ >= bytes_.size(); }

  std::uint8_t u8() { return done() ? 0 : static_cast<std::uint8_t>(bytes_[position_++]); }
  std::uint16_t u16() { return static_cast<std::uint16_t>(u8() | u8() << 8); }
  std::int64_t i64() {
    std::uint64_t value = 0;
    for (int shift = 0; shift < 64; shift += 8) value |= std::uint64_t{u8()} << shift;
    return static_cast<std::int64_t>(value);
  }
  double f64() {
    const std::int64_t bits = i64();
    double value;
    std::memcpy(&value, &bits, sizeof value);
    return value;
  }
  /// LEB128, at most 10 bytes.
  std::uint64_t varint() {
    std::uint64_t value = 0;
    for (int shift = 0; shift < 70; shift += 7) {
      const std::uint8_t byte = u8();
      value |= std::uint64_t{byte & 0x7Fu} << shift;
      if ((byte & 0x80) == 0) break;
    }
    return value;
  }
  std::string string() {
    std::size_t length = u8();
    if (length == 255) length = u16();
    const std::size_t available = std::min(length, bytes_.size() - std::min(position_, bytes_.size()));
    std::string value(bytes_.substr(std::min(position_, bytes_.size()), available));
    position_ += available;
    return value;
  }

 private:
  std::string_view bytes_;
  std::size_t position_ = 0;
};

class ProgramWriter {
 public:
  void action(Op op, int slot = 0) { u8(static_cast<std::uint8_t>(slot << 4 | static_cast<int>(op))); }
  void u8(std::uint8_t value) { bytes_.push_back(static_cast<char>(value)); }
  void u16(std::uint16_t value) {
    u8(static_cast<std::uint8_t>(value));
    u8(static_cast<std::uint8_t>(value >> 8));
  }
  void i64(std::int64_t value) {
    for (int shift = 0; shift < 64; shift += 8)
      u8(static_cast<std::uint8_t>(static_cast<std::uint64_t>(value) >> shift));
  }
  void f64(double value) {
    std::int64_t bits;
    std::memcpy(&bits, &value, sizeof bits);
    i64(bits);
  }
  void varint(std::uint64_t value) {
    while (value >= 0x80) {
      u8(static_cast<std::uint8_t>(value | 0x80));
      value >>= 7;
    }
    u8(static_cast<std::uint8_t>(value));
  }
  void string(std::string_view value) {
    if (value.size() < 255) {
      u8(static_cast<std::uint8_t>(value.size()));
    } else {
      u8(255);
      u16(static_cast<std::uint16_t>(value.size()));
    }
    bytes_.append(value.substr(0, 0xFFFF));
  }

  const std::string& bytes() const { return bytes_; }

 private:
  std::string bytes_;
};

}  // namespace lipsync::fuzz
