// Reading, checking and staging the TLS files (tls.hpp). OpenSSL (libcrypto)
// parses the PEM and checks that the key belongs to the certificate, so that a
// mistake is reported here, naming the file, rather than as failed handshakes.
#include "tls.hpp"

#include <grpcpp/security/server_credentials.h>
#include <grpcpp/security/tls_certificate_provider.h>
#include <grpcpp/security/tls_credentials_options.h>
#include <openssl/bio.h>
#include <openssl/err.h>
#include <openssl/pem.h>
#include <openssl/x509.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>
#include <system_error>
#include <vector>

#include "lipsync/server/config.hpp"

namespace lipsync::server {
namespace {

std::string read_whole(const std::string& flag, const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw TlsError(flag + ": cannot read '" + path + "': " + std::strerror(errno));
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

struct BioDeleter {
  void operator()(BIO* bio) const { BIO_free(bio); }
};
struct X509Deleter {
  void operator()(X509* certificate) const { X509_free(certificate); }
};
struct KeyDeleter {
  void operator()(EVP_PKEY* key) const { EVP_PKEY_free(key); }
};
using Certificate = std::unique_ptr<X509, X509Deleter>;

std::unique_ptr<BIO, BioDeleter> memory_bio(const std::string& text) {
  return std::unique_ptr<BIO, BioDeleter>(BIO_new_mem_buf(text.data(), static_cast<int>(text.size())));
}

/// Every certificate in `pem`; TlsError naming the file if there is none.
std::vector<Certificate> parse_certificates(const std::string& flag, const std::string& path, const std::string& pem) {
  auto bio = memory_bio(pem);
  std::vector<Certificate> certificates;
  while (X509* certificate = PEM_read_bio_X509(bio.get(), nullptr, nullptr, nullptr)) {
    certificates.emplace_back(certificate);
  }
  ERR_clear_error();  // the end of the input reads as an error
  if (certificates.empty()) throw TlsError(flag + ": '" + path + "' holds no PEM certificate");
  return certificates;
}

void check_not_expired(const std::string& flag, const std::string& path, const Certificate& certificate) {
  if (X509_cmp_current_time(X509_get0_notAfter(certificate.get())) < 0) {
    throw TlsError(flag + ": the certificate in '" + path + "' has expired");
  }
}

/// Where the staged copies go: $TMPDIR when set, else /dev/shm (memory, and writable under
/// a read-only root file system), else the system's temporary directory.
std::filesystem::path staging_parent() {
  if (const char* tmpdir = std::getenv("TMPDIR"); tmpdir != nullptr && *tmpdir != '\0') return tmpdir;
  if (::access("/dev/shm", W_OK | X_OK) == 0) return "/dev/shm";
  return std::filesystem::temp_directory_path();
}

}  // namespace

TlsMaterial read_tls_material(const std::string& cert_path, const std::string& key_path,
                              const std::string& client_ca_path) {
  if (cert_path.empty() != key_path.empty()) {
    throw TlsError(cert_path.empty() ? "--tls-key: needs --tls-cert (the certificate of that key)"
                                     : "--tls-cert: needs --tls-key (the certificate's private key)");
  }
  if (cert_path.empty()) {
    throw TlsError("--tls-client-ca: needs --tls-cert and --tls-key (client certificates are checked over TLS)");
  }
  TlsMaterial material;
  material.certificate_chain = read_whole("--tls-cert", cert_path);
  material.private_key = read_whole("--tls-key", key_path);
  const auto chain = parse_certificates("--tls-cert", cert_path, material.certificate_chain);
  check_not_expired("--tls-cert", cert_path, chain.front());
  auto key_bio = memory_bio(material.private_key);
  const std::unique_ptr<EVP_PKEY, KeyDeleter> key(PEM_read_bio_PrivateKey(key_bio.get(), nullptr, nullptr, nullptr));
  ERR_clear_error();
  if (!key) throw TlsError("--tls-key: '" + key_path + "' holds no PEM private key (or one with a passphrase)");
  if (X509_check_private_key(chain.front().get(), key.get()) != 1) {
    ERR_clear_error();
    throw TlsError("--tls-key: the key in '" + key_path + "' does not belong to the certificate in '" + cert_path +
                   "' (--tls-cert)");
  }
  if (!client_ca_path.empty()) {
    material.client_ca = read_whole("--tls-client-ca", client_ca_path);
    parse_certificates("--tls-client-ca", client_ca_path, material.client_ca);
  }
  return material;
}

TlsCredentials::TlsCredentials(const ServerConfig& config)
    : cert_path_(config.tls_cert),
      key_path_(config.tls_key),
      client_ca_path_(config.tls_client_ca),
      mutual_(!config.tls_client_ca.empty()) {
  const TlsMaterial material = read_tls_material(cert_path_, key_path_, client_ca_path_);
  const std::filesystem::path parent = staging_parent();
  std::string pattern = (parent / "lipsyncd-tls-XXXXXX").string();
  if (::mkdtemp(pattern.data()) == nullptr) {
    throw TlsError("cannot create a private directory for the TLS files in " + parent.string() + ": " +
                   std::strerror(errno) + " (set TMPDIR to a writable directory)");
  }
  staging_ = pattern;  // mkdtemp makes it 0700
  stage(material);
  const std::filesystem::path current = staging_ / "current";
  provider_ = std::make_shared<grpc::experimental::FileWatcherCertificateProvider>(
      (current / "key.pem").string(), (current / "cert.pem").string(),
      mutual_ ? (current / "client-ca.pem").string() : std::string(), kRefreshSeconds);
}

TlsCredentials::~TlsCredentials() {
  provider_.reset();
  std::error_code ignored;
  std::filesystem::remove_all(staging_, ignored);
}

std::shared_ptr<grpc::ServerCredentials> TlsCredentials::server_credentials() const {
  grpc::experimental::TlsServerCredentialsOptions options(provider_);
  options.watch_identity_key_cert_pairs();
  if (mutual_) {
    options.watch_root_certs();
    options.set_cert_request_type(GRPC_SSL_REQUEST_AND_REQUIRE_CLIENT_CERTIFICATE_AND_VERIFY);
  } else {
    options.set_cert_request_type(GRPC_SSL_DONT_REQUEST_CLIENT_CERTIFICATE);
  }
  return grpc::experimental::TlsServerCredentials(options);
}

void TlsCredentials::reload() { stage(read_tls_material(cert_path_, key_path_, client_ca_path_)); }

// Each set goes to a new directory gen-N; the link `current` is then replaced by
// rename, so the provider reads either the whole old set or the whole new one
// (it re-reads when a file's time changed while it read). The set before the
// previous one is removed: the provider may still be reading the previous one.
void TlsCredentials::stage(const TlsMaterial& material) {
  const std::string name = "gen-" + std::to_string(++generation_);
  const std::filesystem::path directory = staging_ / name;
  std::filesystem::create_directory(directory);
  const auto write = [&](const char* file, const std::string& text) {
    const std::filesystem::path path = directory / file;
    std::ofstream(path, std::ios::binary) << text;
    ::chmod(path.c_str(), 0600);
  };
  write("cert.pem", material.certificate_chain);
  write("key.pem", material.private_key);
  if (mutual_) write("client-ca.pem", material.client_ca);
  const std::filesystem::path link = staging_ / "current.next";
  std::error_code ignored;
  std::filesystem::remove(link, ignored);
  std::filesystem::create_directory_symlink(name, link);
  std::filesystem::rename(link, staging_ / "current");
  if (generation_ > 2) std::filesystem::remove_all(staging_ / ("gen-" + std::to_string(generation_ - 2)), ignored);
}

}  // namespace lipsync::server
