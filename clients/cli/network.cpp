#include "network.hpp"

#include <chrono>
#include <cstdlib>

#include "cli_error.hpp"
#include "lipsync/visemes.hpp"

namespace lipsync::cli {

std::string server_address(const Arguments& arguments) {
  std::string address = arguments.value("server").value_or(std::string(kDefaultServer));
  if (address.empty()) throw UsageError("--server: the address must not be empty (HOST:PORT)");
  return address;
}

void set_track_request_options(const Arguments& arguments, TrackFormat format,
                               client::v1::AnimationSettings& settings) {
  settings.mutable_outputs()->set_channels(true);
  settings.mutable_outputs()->set_arkit(format != TrackFormat::csv);  // the server's retargeting for its model
  if (const auto model_name = arguments.value("server-model")) {
    if (model_name->empty())
      throw UsageError("--server-model: the name must not be empty (see 'lipsync server-models')");
    settings.set_model(*model_name);
  }
  if (const auto session = arguments.value("session")) {
    if (session->empty()) throw UsageError("--session: the name must not be empty");
    settings.set_session(*session);
  }
}

void set_viseme_request_option(const Arguments& arguments, client::v1::AnimationSettings& settings) {
  const auto name = arguments.value("visemes");
  if (!name) return;
  const std::optional<VisemeVocabulary> vocabulary = viseme_vocabulary_from_string(*name);
  if (!vocabulary) {
    throw UsageError("--visemes: unknown vocabulary '" + *name + "' (choose oculus, azure, polly or rhubarb)");
  }
  if (settings.session().empty()) {
    throw UsageError("--visemes needs --session: the visemes go to the session's subscribers and viewers");
  }
  client::v1::VisemeOutput& visemes = *settings.mutable_outputs()->mutable_visemes();
  visemes.set_enabled(true);
  switch (*vocabulary) {
    case VisemeVocabulary::oculus:
      visemes.set_vocabulary(client::v1::VISEME_VOCABULARY_OCULUS);
      break;
    case VisemeVocabulary::azure:
      visemes.set_vocabulary(client::v1::VISEME_VOCABULARY_AZURE);
      break;
    case VisemeVocabulary::polly:
      visemes.set_vocabulary(client::v1::VISEME_VOCABULARY_POLLY);
      break;
    case VisemeVocabulary::rhubarb:
      visemes.set_vocabulary(client::v1::VISEME_VOCABULARY_RHUBARB);
      break;
  }
}

client::v1::SubscribeRequest::Start subscribe_start(const Arguments& arguments) {
  return arguments.flag("from-now") ? client::v1::SubscribeRequest::START_FROM_NOW
                                    : client::v1::SubscribeRequest::START_FROM_BEGINNING;
}

SessionWait::SessionWait(const Arguments& arguments)
    : wait_(parse_setting_option(arguments, "wait", kWaitSetting)),
      give_up_(std::chrono::steady_clock::now() + wait_) {}

void SessionWait::start() { give_up_ = std::chrono::steady_clock::now() + wait_; }

bool SessionWait::asks_again(grpc::StatusCode code) const {
  return code == grpc::StatusCode::NOT_FOUND && std::chrono::steady_clock::now() < give_up_;
}

client::ClientOptions connection_options(const Arguments& arguments) {
  client::ClientOptions options;
  options.tls.enabled = arguments.flag("tls");
  for (const auto& [name, file] :
       {std::pair{"ca", &options.tls.ca_file}, {"cert", &options.tls.cert_file}, {"key", &options.tls.key_file}}) {
    if (const auto value = arguments.value(name)) {
      if (value->empty()) throw UsageError("--" + std::string(name) + ": the file name must not be empty");
      *file = *value;
    }
  }
  if (options.tls.cert_file.empty() != options.tls.key_file.empty()) {
    throw UsageError("--cert and --key go together (a client certificate and its private key)");
  }
  if (const auto key = arguments.value("api-key")) {
    options.api_key = *key;
  } else if (const char* from_environment = std::getenv("LIPSYNC_API_KEY")) {
    options.api_key = from_environment;
  }
  return options;
}

bool is_loopback_address(std::string_view address) {
  if (address.starts_with("unix:")) return true;
  if (address.starts_with("ipv4:") || address.starts_with("dns:")) {
    address.remove_prefix(address.find(':') + 1);
    if (address.starts_with("///")) address.remove_prefix(3);
  }
  if (address.starts_with("[::1]:") || address.starts_with("ipv6:[::1]:")) return true;
  const std::string_view host = address.substr(0, address.rfind(':'));
  if (host == "localhost") return true;
  if (!host.starts_with("127.")) return false;
  return host.find_first_not_of("0123456789.") == std::string_view::npos;
}

std::int64_t unix_now_us() {
  return std::chrono::duration_cast<std::chrono::microseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

std::int64_t steady_now_us() {
  return std::chrono::duration_cast<std::chrono::microseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

}  // namespace lipsync::cli
