// What a channel to lipsyncd carries for security: the TLS credentials from the PEM files the
// user names (plaintext unless asked), the API key as `authorization: Bearer <key>` on every
// call, and the hint printed when a server does not answer (is it there, does it need TLS, do the
// files match).
#include <fstream>
#include <sstream>

#include "lipsync/client/animation_client.hpp"

namespace lipsync::client {

namespace {

std::string read_pem(const std::string& what, const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    throw CallError("setting up TLS", grpc::StatusCode::INVALID_ARGUMENT,
                    "cannot read the " + what + " '" + path + "'");
  }
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

}  // namespace

std::shared_ptr<grpc::ChannelCredentials> channel_credentials(const TlsOptions& tls) {
  if (!tls.on()) return grpc::InsecureChannelCredentials();
  if (tls.cert_file.empty() != tls.key_file.empty()) {
    throw CallError("setting up TLS", grpc::StatusCode::INVALID_ARGUMENT,
                    "a client certificate needs its key and a key its certificate (--cert and --key together)");
  }
  grpc::SslCredentialsOptions options;
  if (!tls.ca_file.empty()) options.pem_root_certs = read_pem("CA file", tls.ca_file);
  if (!tls.cert_file.empty()) {
    options.pem_cert_chain = read_pem("client certificate", tls.cert_file);
    options.pem_private_key = read_pem("client key", tls.key_file);
  }
  return grpc::SslCredentials(options);
}

void add_api_key(grpc::ClientContext& context, const std::string& api_key) {
  if (!api_key.empty()) context.AddMetadata(std::string(kAuthorizationMetadataKey), "Bearer " + api_key);
}

std::string unreachable_hint(const TlsOptions& tls) {
  return tls.on() ? "(is lipsyncd running there with TLS, and do --ca, --cert and --key match its certificate and "
                    "client CA? see --server)"
                  : "(is lipsyncd running there? if it uses TLS, add --ca FILE or --tls; see --server)";
}

}  // namespace lipsync::client
