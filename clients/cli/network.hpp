// What the network commands (stream, speak, subscribe, play, loadtest, server-models)
// share: the --server option, the connection options (TLS and the API key), the
// loopback check and the clocks; the --server-model and --session options of the
// commands that produce a track. Received
// tracks are written by received_track_writer.hpp.
#pragma once

#include <array>
#include <chrono>
#include <string>
#include <string_view>

#include "arguments.hpp"
#include "lipsync/client/animation_client.hpp"
#include "lipsync/setting_ranges.hpp"
#include "lipsync/track_writer.hpp"
#include "setting_help.hpp"

namespace lipsync::cli {

inline constexpr std::string_view kDefaultServer = "127.0.0.1:50051";

inline constexpr OptionSpec kServerOption = {"server", 0, "ADDR", "lipsyncd address, HOST:PORT", kDefaultServer};

inline constexpr OptionSpec kServerModelOption = {
    "server-model", 0, "NAME",
    "the server's model to animate with (see 'lipsync server-models'); the output is named after its channels",
    "the server's default model"};
inline constexpr OptionSpec kSessionOption = {"session", 0, "NAME",
                                              "publish the frames under this session name for subscribers", "private"};

/// Into `settings`: the outputs a track written in `format` needs (channels, and the
/// server's ARKit weights unless csv), --server-model and --session (UsageError if empty).
void set_track_request_options(const Arguments& arguments, TrackFormat format, client::v1::AnimationSettings& settings);

/// --visemes of the commands that publish a session (speak, stream): what the session's
/// subscribers and viewers get besides the frames; the track the command writes is unchanged.
inline constexpr OptionSpec kVisemesOption = {
    "visemes", 0, "VOCABULARY",
    "also publish viseme weights and events in VOCABULARY (oculus, azure, polly or rhubarb) for the session's "
    "subscribers and viewers (needs --session)",
    "none"};

/// Into `settings`: --visemes (UsageError for an unknown vocabulary, or without --session, which
/// set_track_request_options has read).
void set_viseme_request_option(const Arguments& arguments, client::v1::AnimationSettings& settings);

/// How to reach a server that uses TLS or API keys (docs/security.md), in kConnectionOptions
/// after kServerOption. The API key may also come from LIPSYNC_API_KEY (kept out of `ps`).
inline constexpr OptionSpec kTlsOption = {"tls", 0, "", "connect with TLS (implied by --ca, --cert and --key)",
                                          "plaintext"};
inline constexpr OptionSpec kCaOption = {"ca", 0, "FILE", "PEM CA bundle that signed the server's certificate",
                                         "the system's roots"};
inline constexpr OptionSpec kCertOption = {"cert", 0, "FILE",
                                           "PEM client certificate, for a server that requires one (with --key)", ""};
inline constexpr OptionSpec kKeyOption = {"key", 0, "FILE", "PEM private key of --cert", ""};
inline constexpr OptionSpec kApiKeyOption = {"api-key", 0, "KEY", "API key, sent as `authorization: Bearer KEY`",
                                             "$LIPSYNC_API_KEY, else none"};

/// The options every network command takes first: where lipsyncd is and how to reach it.
inline constexpr std::array kConnectionOptions = {kServerOption, kTlsOption, kCaOption,
                                                  kCertOption,   kKeyOption, kApiKeyOption};

/// --timeout S: how long a command waits for its call. Each command states its range and default
/// once, as an IntSetting, with the help's lead ("give up when ... after S seconds"); its help and
/// its check (parse_setting_option) both come from that declaration.
template <FixedText Help, IntSetting Setting>
inline constexpr OptionSpec kTimeoutOption = {"timeout", 0, "S", kRangedHelp<Help, Setting>.view(),
                                              kDefaultText<Setting>.view()};

/// --wait S of the commands that follow a session (subscribe, play).
inline constexpr IntSetting kWaitSetting = {0, 3600, 0};
inline constexpr OptionSpec kWaitOption = {
    "wait", 0, "S",
    kRangedHelp<"if the session does not exist yet, keep asking for up to S seconds", kWaitSetting>.view(),
    kDefaultText<kWaitSetting>.view()};

/// --from-now of the commands that follow a session: only frames produced after joining.
inline constexpr OptionSpec kFromNowOption = {"from-now", 0, "", "only frames produced after joining",
                                              "replay the frames the server still holds, then follow"};

/// Where a follower starts: --from-now, else from the beginning of what the server holds.
client::v1::SubscribeRequest::Start subscribe_start(const Arguments& arguments);

/// The rule of --wait: a session that does not exist yet (NOT_FOUND) is asked for again, every
/// kPause, until S seconds after the first ask; any other status, or NOT_FOUND after that, stands.
class SessionWait {
 public:
  static constexpr std::chrono::milliseconds kPause{50};

  /// Reads and checks --wait (UsageError naming it).
  explicit SessionWait(const Arguments& arguments);
  /// The S seconds start now: call once, before the first ask.
  void start();
  /// Whether a call that ended with `code` is to be made again.
  bool asks_again(grpc::StatusCode code) const;

 private:
  std::chrono::seconds wait_;
  std::chrono::steady_clock::time_point give_up_;
};

/// --server, checked to be non-empty.
std::string server_address(const Arguments& arguments);

/// ClientOptions with the TLS settings and API key of the command line (and LIPSYNC_API_KEY).
client::ClientOptions connection_options(const Arguments& arguments);

/// Whether `address` names this machine (127.x.y.z, localhost, [::1], unix:).
bool is_loopback_address(std::string_view address);

/// Microseconds on the wall clock (the "unix" media clock) and on the steady clock.
std::int64_t unix_now_us();
std::int64_t steady_now_us();

}  // namespace lipsync::cli
