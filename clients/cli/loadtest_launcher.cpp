// `lipsync loadtest`: runs the load generator, a program of its own
// (lipsync-loadtest, tools/loadtest/), installed and built beside lipsync.
//
// The generator carries its own HTTP/2 client on nghttp2 and a synthetic
// workload; users who render and stream need neither, so lipsync does not link
// them. The command stays where users know it: lipsync replaces itself with
// the generator (exec), which then owns the terminal, the arguments and the
// exit status.
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <iostream>
#include <string>
#include <system_error>
#include <vector>

#include "cli_error.hpp"
#include "commands.hpp"

namespace lipsync::cli {

namespace {

constexpr const char* kGeneratorName = "lipsync-loadtest";

/// The generator beside this executable (the build tree and an installed prefix
/// both put them in one folder).
std::filesystem::path generator_path() {
  std::error_code error;
  const std::filesystem::path self = std::filesystem::read_symlink("/proc/self/exe", error);
  if (error) throw FileError("cannot find where lipsync runs from (/proc/self/exe): " + error.message());
  return self.parent_path() / kGeneratorName;
}

}  // namespace

int run_loadtest(std::span<const std::string_view> args) {
  const std::filesystem::path generator = generator_path();
  if (::access(generator.c_str(), X_OK) != 0) {
    throw FileError("loadtest needs the load generator " + generator.string() +
                    ", which is not there: build it (target lipsync-loadtest, tools/loadtest/) or install it "
                    "beside lipsync");
  }
  std::vector<std::string> words = {kGeneratorName};
  words.insert(words.end(), args.begin(), args.end());
  std::vector<char*> argv;
  argv.reserve(words.size() + 1);
  for (std::string& word : words) argv.push_back(word.data());
  argv.push_back(nullptr);
  std::cout.flush();
  std::cerr.flush();
  std::fflush(nullptr);
  ::execv(generator.c_str(), argv.data());
  throw FileError("cannot run the load generator " + generator.string() + ": " +
                  std::error_code(errno, std::generic_category()).message());
}

}  // namespace lipsync::cli
