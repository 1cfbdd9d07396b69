// Transport security: the server's TLS credentials, checked when read and
// reloadable while the server runs.
//
// gRPC 1.51 can hand an accepted file descriptor only to an insecure channel,
// so with TLS configured gRPC listens itself (server.cpp) with
// TlsServerCredentials fed by a FileWatcherCertificateProvider. That provider
// re-reads its files every second and serves what it read to new handshakes;
// it never drops a connection. It does not watch the operator's files: a
// half-copied certificate, or a new certificate beside the old key, would be
// served as it stands. It watches a private staging copy instead, removed at
// exit (a 0700 directory in $TMPDIR, else /dev/shm, else /tmp; files 0600).
// The operator's files are read and checked (PEM that parses, the key that
// matches the certificate, not expired, a CA bundle with at least one
// certificate), and only a good set is staged, swapped in as a whole by
// renaming a symbolic link. A bad set at start-up is an error naming the file;
// at reload it is logged and the old set stays.
#pragma once

#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>

namespace grpc {
class ServerCredentials;
namespace experimental {
class FileWatcherCertificateProvider;
}
}  // namespace grpc

namespace lipsync::server {

struct ServerConfig;

/// A TLS file that cannot be used; the message names the flag, the file and why.
class TlsError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// The PEM texts of one certificate set, checked.
struct TlsMaterial {
  std::string certificate_chain;
  std::string private_key;
  std::string client_ca;  ///< "" without mTLS
};

/// Reads and checks the files of --tls-cert, --tls-key and --tls-client-ca ("": none):
/// a certificate needs its key, a client CA both. Throws TlsError.
TlsMaterial read_tls_material(const std::string& cert_path, const std::string& key_path,
                              const std::string& client_ca_path);

class TlsCredentials {
 public:
  /// Reads the files of `config` (any of the three set) and stages them. Throws TlsError.
  explicit TlsCredentials(const ServerConfig& config);
  ~TlsCredentials();
  TlsCredentials(const TlsCredentials&) = delete;
  TlsCredentials& operator=(const TlsCredentials&) = delete;

  /// Credentials that serve the staged set; client certificates required when a CA is given.
  std::shared_ptr<grpc::ServerCredentials> server_credentials() const;

  /// Reads the files again and stages them: new handshakes get them within about a
  /// second (the provider's refresh); open connections keep theirs. Throws TlsError
  /// (the staged set is then unchanged).
  void reload();

  /// How long the provider may take to serve a reloaded set.
  static constexpr int kRefreshSeconds = 1;

 private:
  void stage(const TlsMaterial& material);

  const std::string cert_path_, key_path_, client_ca_path_;
  const bool mutual_;
  std::filesystem::path staging_;
  unsigned generation_ = 0;
  std::shared_ptr<grpc::experimental::FileWatcherCertificateProvider> provider_;
};

}  // namespace lipsync::server
