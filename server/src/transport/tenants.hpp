// Tenants: who may call lipsyncd, and how much of it each may use.
//
// Without --api-keys the server is open, as it always was: every caller is the
// one anonymous tenant "" and only the global limits apply. With a key file,
// every call must carry `authorization: Bearer <key>` metadata naming a key of
// the file (UNAUTHENTICATED otherwise). The file holds only SHA-256 hashes of
// the keys, never the keys: a presented key is hashed and looked up. A key
// belongs to a tenant and may be limited to some calls (PERMISSION_DENIED for
// the others); a tenant has quotas (RESOURCE_EXHAUSTED naming the quota and its
// value beyond them):
//
//   max_streams              Animate + Subscribe streams open at once
//   max_sessions             named sessions live at once (their producers running)
//   max_subscribers          Subscribe streams open at once
//   max_mesh_streams         calls with the mesh output at once (Animate and Render)
//   max_phonemes_per_second  phonemes received (Animate and Render), a token bucket
//                            that holds one second's worth and may go into debt:
//                            a call is refused while the bucket is empty, so a large
//                            Render is taken whole and the next calls wait for it
//
// A quota left out is unlimited (the global limits still apply). Sessions are
// namespaced by tenant (SessionRegistry is keyed by session_key): a tenant sees
// only its own sessions, and another tenant's session reads as one that does not
// exist. The key file is re-read on SIGHUP; counts are kept per tenant name
// across reloads, and new quotas apply to what is admitted after the reload.
//
// The first part (the key file, hashing, TenantUsage) is plain data and
// counting, unit-tested on its own; Tenants and Caller are the gRPC edge.
#pragma once

#include <grpcpp/server_context.h>
#include <grpcpp/support/status.h>

#include <chrono>
#include <cstddef>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <stdexcept>
#include <string>
#include <string_view>

namespace lipsync::server {

/// A key file that cannot be used; the message names the file and the entry.
class KeyFileError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

inline constexpr std::size_t kUnlimited = std::numeric_limits<std::size_t>::max();

/// The counted quotas (held while a call runs), in the order of TenantUsage's counts.
enum class Quota { streams, sessions, subscribers, mesh_streams };

struct TenantQuotas {
  std::size_t max_streams = kUnlimited;
  std::size_t max_sessions = kUnlimited;
  std::size_t max_subscribers = kUnlimited;
  std::size_t max_mesh_streams = kUnlimited;
  std::size_t max_phonemes_per_second = kUnlimited;

  /// The limit of a counted quota.
  std::size_t limit(Quota quota) const;
};

/// The quota's name in the key file and in refusals ("max_streams").
std::string_view quota_name(Quota quota);

struct ApiKey {
  std::string name;  ///< for logs ("studio-a-tts"); never the key
  std::string tenant;
  std::set<std::string> calls;  ///< the methods it may call ("Animate", ...); empty: all
};

struct KeyTable {
  std::map<std::string, ApiKey, std::less<>> keys_by_hash;  ///< lowercase hex SHA-256 -> key
  std::map<std::string, std::shared_ptr<const TenantQuotas>, std::less<>> tenants;
};

/// The lowercase hexadecimal SHA-256 of `key` (OpenSSL's libcrypto).
std::string sha256_hex(std::string_view key);

/// Parses a key file's JSON text; `source` names it in errors. Throws KeyFileError.
KeyTable parse_key_file(const std::string& text, const std::string& source);
/// Reads and parses the file at `path`. Throws KeyFileError.
KeyTable read_key_file(const std::string& path);

/// One tenant's use of its quotas. Thread-safe.
class TenantUsage {
 public:
  using Clock = std::chrono::steady_clock;

  explicit TenantUsage(std::string tenant) : tenant_(std::move(tenant)) {}

  /// Counts one more of `quota` in, or RESOURCE_EXHAUSTED naming the quota and its value.
  grpc::Status acquire(Quota quota, std::size_t limit);
  void release(Quota quota);
  std::size_t in_use(Quota quota) const;

  /// Takes `count` phonemes from the tenant's bucket at `now`, or RESOURCE_EXHAUSTED
  /// while it is empty.
  grpc::Status take_phonemes(std::size_t count, std::size_t per_second, Clock::time_point now);

 private:
  const std::string tenant_;
  mutable std::mutex mutex_;
  std::size_t held_[4] = {};
  double phoneme_tokens_ = 0;
  bool bucket_started_ = false;
  Clock::time_point bucket_time_;
};

/// One unit of a quota, held while a call runs (released when destroyed).
class QuotaHold {
 public:
  QuotaHold() = default;
  QuotaHold(std::shared_ptr<TenantUsage> usage, Quota quota) : usage_(std::move(usage)), quota_(quota) {}
  QuotaHold(QuotaHold&& other) noexcept : usage_(std::move(other.usage_)), quota_(other.quota_) {}
  QuotaHold& operator=(QuotaHold&& other) noexcept;
  QuotaHold(const QuotaHold&) = delete;
  QuotaHold& operator=(const QuotaHold&) = delete;
  ~QuotaHold();

 private:
  std::shared_ptr<TenantUsage> usage_;
  Quota quota_ = Quota::streams;
};

/// Who is calling: the tenant and its quotas as they were when the call began.
class Caller {
 public:
  /// The anonymous caller of an open server: no quotas.
  Caller() = default;
  Caller(std::string tenant, std::shared_ptr<const TenantQuotas> quotas, std::shared_ptr<TenantUsage> usage)
      : tenant_(std::move(tenant)), quotas_(std::move(quotas)), usage_(std::move(usage)) {}

  const std::string& tenant() const { return tenant_; }
  /// The registry key of this caller's session `name`: the tenant's namespace.
  std::string session_key(const std::string& name) const;

  /// Holds one unit of `quota` in `hold`, or RESOURCE_EXHAUSTED.
  grpc::Status hold(Quota quota, QuotaHold& hold) const;
  /// Counts `count` phonemes against max_phonemes_per_second.
  grpc::Status take_phonemes(std::size_t count) const;

 private:
  std::string tenant_;
  std::shared_ptr<const TenantQuotas> quotas_;
  std::shared_ptr<TenantUsage> usage_;
};

/// The key file in force, and every tenant's usage.
class Tenants {
 public:
  static constexpr const char* kMetadataKey = "authorization";

  /// `key_file` "" runs the server open. Throws KeyFileError.
  explicit Tenants(std::string key_file);

  bool open() const { return key_file_.empty(); }
  /// The tenant whose namespace holds the registry key `session_key` (Caller::session_key).
  std::string tenant_of_session_key(const std::string& session_key) const;
  /// "open to every caller (no --api-keys)" or "N API keys of M tenants from FILE".
  std::string describe() const;

  /// Who calls `method` ("Animate") on `context`: OK and `caller`, or UNAUTHENTICATED
  /// (no key, a malformed header, an unknown key) or PERMISSION_DENIED (a key not
  /// allowed to call `method`).
  grpc::Status authenticate(const grpc::CallbackServerContext& context, std::string_view method, Caller& caller) const;
  /// The same for an `authorization` value given directly (null: none was sent), as the browser
  /// viewer's HTTP requests carry it.
  grpc::Status authenticate_value(const std::string_view* authorization, std::string_view method, Caller& caller) const;

  /// Reads the key file again; throws KeyFileError and keeps the old table if it is bad.
  void reload();

 private:
  const std::string key_file_;
  mutable std::mutex mutex_;
  std::shared_ptr<const KeyTable> table_;
  mutable std::map<std::string, std::shared_ptr<TenantUsage>, std::less<>> usage_;
};

}  // namespace lipsync::server
