// lipsync-loadtest: the load generator of lipsyncd, a program of its own so
// that the user's `lipsync` links no HTTP/2 client of ours. Users run it as
// `lipsync loadtest` (clients/cli/loadtest_launcher.cpp), or directly; either
// way it speaks as that command (its help, its errors, its exit statuses).
#include <string_view>
#include <vector>

#include "command_main.hpp"
#include "commands.hpp"

int main(int argc, char** argv) {
  using namespace lipsync::cli;
  const std::vector<std::string_view> args(argv + 1, argv + argc);
  end_process(report_failures([&] { return run_loadtest(args); }));
}
