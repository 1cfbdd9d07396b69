// `lipsync health`: asks a lipsyncd the gRPC health protocol (grpc.health.v1.Health/Check, the
// whole server) and exits 0 when it answers SERVING, 1 otherwise (NOT_SERVING while it drains,
// unreachable, or no answer in time). For container health checks (Dockerfile) and scripts.
// Debian ships no generated health stubs, so the two tiny messages are encoded by hand:
// HealthCheckRequest{service = ""} is empty; HealthCheckResponse{status} is field 1, a varint.
#include <grpcpp/generic/generic_stub.h>
#include <grpcpp/grpcpp.h>

#include <array>
#include <chrono>
#include <future>
#include <iostream>

#include "arguments.hpp"
#include "cli_error.hpp"
#include "commands.hpp"
#include "network.hpp"

namespace lipsync::cli {
namespace {

/// --timeout: a health check answers at once or not at all.
constexpr IntSetting kHealthTimeoutSetting = {1, 3600, 3};

constexpr auto kOptions =
    join(kConnectionOptions,
         std::to_array<OptionSpec>({
             kTimeoutOption<"give up when the server has not answered after S seconds", kHealthTimeoutSetting>,
         }));

constexpr std::string_view kUsage = "lipsync health [options]";
constexpr std::string_view kDescription =
    "Asks lipsyncd's gRPC health service (grpc.health.v1) whether it serves. Prints SERVING\n"
    "and exits 0, or prints the status (NOT_SERVING while it drains) and exits 1; a server that\n"
    "does not answer within --timeout (a draining one refuses connections) exits 1 too.";

constexpr std::string_view kStatusNames[] = {"UNKNOWN", "SERVING", "NOT_SERVING", "SERVICE_UNKNOWN"};

}  // namespace

int run_health(std::span<const std::string_view> args) {
  const Arguments arguments = Arguments::parse(args, kOptions, "health");
  if (print_help_if_asked(arguments, kUsage, kDescription, kOptions, std::cout)) return 0;
  if (!arguments.positional().empty()) throw UsageError("health takes no arguments (see 'lipsync health --help')");
  const std::string address = server_address(arguments);
  const int timeout_s = parse_setting_option(arguments, "timeout", kHealthTimeoutSetting);

  const client::ClientOptions options = connection_options(arguments);
  grpc::GenericStub stub(grpc::CreateChannel(address, client::channel_credentials(options.tls)));
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(timeout_s));
  context.set_wait_for_ready(true);  // a server still starting up gets the whole timeout
  const grpc::Slice nothing;         // HealthCheckRequest{service = ""}: no bytes (yet a valid buffer)
  const grpc::ByteBuffer request(&nothing, 1);
  grpc::ByteBuffer response;
  std::promise<grpc::Status> done;
  stub.UnaryCall(&context, "/grpc.health.v1.Health/Check", grpc::StubOptions(), &request, &response,
                 [&done](grpc::Status status) { done.set_value(std::move(status)); });
  const grpc::Status status = done.get_future().get();
  if (!status.ok()) {
    std::cerr << "lipsync: lipsyncd at " << address
              << " did not answer: " << client::status_code_name(status.error_code()) << ": " << status.error_message();
    const bool unreachable = status.error_code() == grpc::StatusCode::DEADLINE_EXCEEDED ||
                             status.error_code() == grpc::StatusCode::UNAVAILABLE;
    if (unreachable) std::cerr << ' ' << client::unreachable_hint(options.tls);
    std::cerr << '\n';
    return 1;
  }
  std::vector<grpc::Slice> slices;
  std::string bytes;
  if (response.Dump(&slices).ok()) {
    for (const grpc::Slice& slice : slices) bytes.append(reinterpret_cast<const char*>(slice.begin()), slice.size());
  }
  const std::size_t serving = bytes.size() == 2 && bytes[0] == '\x08' ? static_cast<std::size_t>(bytes[1]) : 0;
  std::cout << (serving < std::size(kStatusNames) ? kStatusNames[serving] : "UNKNOWN") << '\n';
  return serving == 1 ? 0 : 1;
}

}  // namespace lipsync::cli
