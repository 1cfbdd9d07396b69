// API keys, tenants and their quotas (tenants.hpp).
#include "tenants.hpp"

#include <openssl/evp.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

namespace lipsync::server {
namespace {

// The methods a key may be limited to.
const std::set<std::string, std::less<>> kMethods = {"Animate",   "Render",     "Speak",
                                                     "Subscribe", "ListModels", "GetModel"};

constexpr std::size_t kMaxTenantName = 64;

bool valid_tenant_name(const std::string& name) {
  return !name.empty() && name.size() <= kMaxTenantName && std::all_of(name.begin(), name.end(), [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_' || c == '.';
  });
}

bool is_sha256_hex(const std::string& text) {
  return text.size() == 64 && std::all_of(text.begin(), text.end(), [](char c) {
           return std::isdigit(static_cast<unsigned char>(c)) || (c >= 'a' && c <= 'f');
         });
}

/// Reads the JSON text of a key file, each error naming `source` and where in it.
class KeyFileParser {
 public:
  explicit KeyFileParser(const std::string& source) : source_(source) {}

  KeyTable parse(const std::string& text) {
    nlohmann::json json;
    try {
      json = nlohmann::json::parse(text);
    } catch (const nlohmann::json::exception& error) {
      fail("", std::string("not valid JSON: ") + error.what());
    }
    if (!json.is_object()) fail("", "expected a JSON object with \"tenants\" and \"keys\"");
    for (const auto& [field, value] : json.items()) {
      if (field != "tenants" && field != "keys") fail(field, "unknown field (expected \"tenants\" and \"keys\")");
    }
    KeyTable table;
    const auto tenants = json.find("tenants");
    if (tenants == json.end() || !tenants->is_object()) fail("tenants", "expected an object of tenant names");
    for (const auto& [name, quotas] : tenants->items()) {
      const std::string where = "tenants." + name;
      if (!valid_tenant_name(name)) {
        fail(where, "a tenant name is 1 to 64 letters, digits, '-', '_' or '.'");
      }
      table.tenants.emplace(name, std::make_shared<const TenantQuotas>(parse_quotas(where, quotas)));
    }
    const auto keys = json.find("keys");
    if (keys == json.end() || !keys->is_array()) fail("keys", "expected an array of keys");
    for (std::size_t i = 0; i < keys->size(); ++i) {
      const std::string where = "keys[" + std::to_string(i) + "]";
      auto [hash, key] = parse_key(where, (*keys)[i], table);
      if (!table.keys_by_hash.emplace(hash, std::move(key)).second) fail(where, "the same sha256 as an earlier key");
    }
    return table;
  }

 private:
  [[noreturn]] void fail(const std::string& where, const std::string& message) const {
    throw KeyFileError("--api-keys: " + source_ + (where.empty() ? "" : ": " + where) + ": " + message);
  }

  TenantQuotas parse_quotas(const std::string& where, const nlohmann::json& json) const {
    if (!json.is_object()) fail(where, "expected an object of quotas");
    TenantQuotas quotas;
    const std::pair<const char*, std::size_t*> fields[] = {
        {"max_streams", &quotas.max_streams},
        {"max_sessions", &quotas.max_sessions},
        {"max_subscribers", &quotas.max_subscribers},
        {"max_mesh_streams", &quotas.max_mesh_streams},
        {"max_phonemes_per_second", &quotas.max_phonemes_per_second},
    };
    for (const auto& [field, value] : json.items()) {
      const std::string& name = field;  // clang 14 (the fuzz build) cannot capture a structured binding
      const auto known =
          std::find_if(std::begin(fields), std::end(fields), [&](const auto& entry) { return name == entry.first; });
      if (known == std::end(fields)) {
        fail(where + "." + field,
             "unknown quota (max_streams, max_sessions, max_subscribers, max_mesh_streams, "
             "max_phonemes_per_second)");
      }
      if (!value.is_number_unsigned() || value.get<std::uint64_t>() > 1'000'000'000) {
        fail(where + "." + field, "expected a whole number from 0 to 1000000000");
      }
      *known->second = value.get<std::size_t>();
    }
    return quotas;
  }

  std::pair<std::string, ApiKey> parse_key(const std::string& where, const nlohmann::json& json,
                                           const KeyTable& table) const {
    if (!json.is_object()) fail(where, "expected an object with \"sha256\" and \"tenant\"");
    std::string hash;
    ApiKey key;
    for (const auto& [field, value] : json.items()) {
      const std::string at = where + "." + field;
      if (field == "calls") {
        if (!value.is_array()) fail(at, "expected an array of method names");
        for (const auto& method : value) {
          if (!method.is_string() || kMethods.count(method.get<std::string>()) == 0) {
            fail(at, "expected method names: Animate, Render, Speak, Subscribe, ListModels, GetModel");
          }
          key.calls.insert(method.get<std::string>());
        }
        continue;
      }
      if (!value.is_string()) fail(at, "expected a string");
      if (field == "sha256") {
        hash = value.get<std::string>();
      } else if (field == "tenant") {
        key.tenant = value.get<std::string>();
      } else if (field == "name") {
        key.name = value.get<std::string>();
      } else {
        fail(at, "unknown field (sha256, tenant, name, calls); keys are stored hashed only");
      }
    }
    if (!is_sha256_hex(hash)) {
      fail(where + ".sha256", "expected 64 lowercase hexadecimal digits (make one with `lipsyncd --hash-key`)");
    }
    if (table.tenants.count(key.tenant) == 0) fail(where + ".tenant", "no tenant '" + key.tenant + "' in \"tenants\"");
    if (key.name.empty()) key.name = hash.substr(0, 8);
    return {hash, key};
  }

  const std::string& source_;
};

std::size_t index_of(Quota quota) { return static_cast<std::size_t>(quota); }

}  // namespace

std::string_view quota_name(Quota quota) {
  switch (quota) {
    case Quota::streams:
      return "max_streams";
    case Quota::sessions:
      return "max_sessions";
    case Quota::subscribers:
      return "max_subscribers";
    case Quota::mesh_streams:
      return "max_mesh_streams";
  }
  return "unknown";
}

std::size_t TenantQuotas::limit(Quota quota) const {
  const std::size_t limits[] = {max_streams, max_sessions, max_subscribers, max_mesh_streams};
  return limits[index_of(quota)];
}

std::string sha256_hex(std::string_view key) {
  std::array<unsigned char, EVP_MAX_MD_SIZE> digest{};
  unsigned int length = 0;
  EVP_Digest(key.data(), key.size(), digest.data(), &length, EVP_sha256(), nullptr);
  static constexpr char kHex[] = "0123456789abcdef";
  std::string hex;
  for (unsigned int i = 0; i < length; ++i) {
    hex += kHex[digest[i] >> 4];
    hex += kHex[digest[i] & 15];
  }
  return hex;
}

KeyTable parse_key_file(const std::string& text, const std::string& source) {
  return KeyFileParser(source).parse(text);
}

KeyTable read_key_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw KeyFileError("--api-keys: cannot read '" + path + "'");
  std::ostringstream text;
  text << in.rdbuf();
  return parse_key_file(text.str(), path);
}

// --- TenantUsage -----------------------------------------------------------------

grpc::Status TenantUsage::acquire(Quota quota, std::size_t limit) {
  std::lock_guard lock(mutex_);
  std::size_t& held = held_[index_of(quota)];
  if (held >= limit) {
    return {grpc::StatusCode::RESOURCE_EXHAUSTED, "tenant '" + tenant_ + "' is at its quota " +
                                                      std::string(quota_name(quota)) + "=" + std::to_string(limit) +
                                                      " (" + std::to_string(held) + " in use)"};
  }
  ++held;
  return grpc::Status::OK;
}

void TenantUsage::release(Quota quota) {
  std::lock_guard lock(mutex_);
  --held_[index_of(quota)];
}

std::size_t TenantUsage::in_use(Quota quota) const {
  std::lock_guard lock(mutex_);
  return held_[index_of(quota)];
}

grpc::Status TenantUsage::take_phonemes(std::size_t count, std::size_t per_second, Clock::time_point now) {
  if (per_second == kUnlimited) return grpc::Status();  // OK, without copying Status::OK
  std::lock_guard lock(mutex_);
  const double capacity = static_cast<double>(per_second);
  if (!bucket_started_) {
    bucket_started_ = true;
    phoneme_tokens_ = capacity;
  } else {
    const double elapsed_s = std::chrono::duration<double>(now - bucket_time_).count();
    phoneme_tokens_ = std::min(capacity, phoneme_tokens_ + capacity * std::max(0.0, elapsed_s));
  }
  bucket_time_ = now;
  if (phoneme_tokens_ <= 0 && count > 0) {
    return {grpc::StatusCode::RESOURCE_EXHAUSTED,
            "tenant '" + tenant_ + "' is over its quota max_phonemes_per_second=" + std::to_string(per_second) +
                " (try again in " + std::to_string(static_cast<long long>(-phoneme_tokens_ / capacity * 1000) + 1) +
                " ms)"};
  }
  phoneme_tokens_ -= static_cast<double>(count);
  return grpc::Status();  // OK
}

QuotaHold& QuotaHold::operator=(QuotaHold&& other) noexcept {
  if (this != &other) {
    if (usage_) usage_->release(quota_);
    usage_ = std::move(other.usage_);
    quota_ = other.quota_;
  }
  return *this;
}

QuotaHold::~QuotaHold() {
  if (usage_) usage_->release(quota_);
}

// --- Caller ----------------------------------------------------------------------

std::string Caller::session_key(const std::string& name) const {
  // Tenant names have no '/', so "tenant/name" is unambiguous; an open server has one namespace.
  return tenant_.empty() ? name : tenant_ + "/" + name;
}

std::string Tenants::tenant_of_session_key(const std::string& session_key) const {
  return open() ? std::string() : session_key.substr(0, session_key.find('/'));
}

grpc::Status Caller::hold(Quota quota, QuotaHold& hold) const {
  if (!usage_) return grpc::Status::OK;
  const std::size_t limit = quotas_->limit(quota);
  if (limit == kUnlimited) return grpc::Status::OK;
  if (grpc::Status status = usage_->acquire(quota, limit); !status.ok()) return status;
  hold = QuotaHold(usage_, quota);
  return grpc::Status::OK;
}

grpc::Status Caller::take_phonemes(std::size_t count) const {
  if (!usage_) return grpc::Status();  // OK
  return usage_->take_phonemes(count, quotas_->max_phonemes_per_second, TenantUsage::Clock::now());
}

// --- Tenants ---------------------------------------------------------------------

Tenants::Tenants(std::string key_file) : key_file_(std::move(key_file)) {
  if (!open()) table_ = std::make_shared<const KeyTable>(read_key_file(key_file_));
}

std::string Tenants::describe() const {
  if (open()) return "open to every caller (no --api-keys): no keys, tenants or quotas";
  std::lock_guard lock(mutex_);
  return std::to_string(table_->keys_by_hash.size()) + " API keys of " + std::to_string(table_->tenants.size()) +
         " tenants from " + key_file_;
}

void Tenants::reload() {
  if (open()) return;
  auto table = std::make_shared<const KeyTable>(read_key_file(key_file_));
  std::lock_guard lock(mutex_);
  table_ = std::move(table);
}

grpc::Status Tenants::authenticate(const grpc::CallbackServerContext& context, std::string_view method,
                                   Caller& caller) const {
  if (open()) return grpc::Status::OK;
  const auto& metadata = context.client_metadata();
  const auto found = metadata.find(kMetadataKey);
  if (found == metadata.end()) return authenticate_value(nullptr, method, caller);
  const std::string_view value(found->second.data(), found->second.size());
  return authenticate_value(&value, method, caller);
}

grpc::Status Tenants::authenticate_value(const std::string_view* authorization, std::string_view method,
                                         Caller& caller) const {
  if (open()) return grpc::Status::OK;
  if (!authorization) {
    return {grpc::StatusCode::UNAUTHENTICATED,
            "this server needs an API key: send the metadata `authorization: Bearer <key>`"};
  }
  const std::string_view value = *authorization;
  constexpr std::string_view kScheme = "bearer ";
  const bool bearer = value.size() > kScheme.size() &&
                      std::equal(kScheme.begin(), kScheme.end(), value.begin(),
                                 [](char a, char b) { return a == std::tolower(static_cast<unsigned char>(b)); });
  if (!bearer) {
    return {grpc::StatusCode::UNAUTHENTICATED, "the authorization metadata must read `Bearer <key>`"};
  }
  const std::string hash = sha256_hex(value.substr(kScheme.size()));
  std::lock_guard lock(mutex_);
  const auto key = table_->keys_by_hash.find(hash);
  if (key == table_->keys_by_hash.end()) {
    return {
        grpc::StatusCode::UNAUTHENTICATED,
        "unknown API key: it is not in this server's key file (check the key sent as `authorization: Bearer <key>`)"};
  }
  if (!key->second.calls.empty() && key->second.calls.count(std::string(method)) == 0) {
    std::string allowed;
    for (const std::string& call : key->second.calls) allowed += (allowed.empty() ? "" : ", ") + call;
    return {grpc::StatusCode::PERMISSION_DENIED, "API key '" + key->second.name + "' of tenant '" + key->second.tenant +
                                                     "' may not call " + std::string(method) + " (it may call " +
                                                     allowed + ")"};
  }
  const std::string& tenant = key->second.tenant;
  auto& usage = usage_[tenant];
  if (!usage) usage = std::make_shared<TenantUsage>(tenant);
  caller = Caller(tenant, table_->tenants.find(tenant)->second, usage);
  return grpc::Status::OK;
}

}  // namespace lipsync::server
