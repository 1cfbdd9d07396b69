// LipsyncCliTest: the fixture of the tests that run the real `lipsync` program.
//
// Each test gets a fresh working directory for the command (which must end up
// holding only what the command wrote) and a second one for its captured stdout
// and stderr; both are removed afterwards. Test files derive their own fixture
// from it (`class CliTest : public testing::LipsyncCliTest {};`) so their test
// names keep saying what they test. The including target defines
// LIPSYNC_CLI_BINARY as the program's path.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <string>
#include <vector>

#include "child_process.hpp"

#ifndef LIPSYNC_CLI_BINARY
#error "LIPSYNC_CLI_BINARY must name the lipsync program (target_compile_definitions)"
#endif

namespace lipsync::testing {

class LipsyncCliTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = make_temp_dir("lipsync-cli-work-");
    capture_ = make_temp_dir("lipsync-cli-capture-");
  }
  void TearDown() override {
    std::filesystem::remove_all(dir_);
    std::filesystem::remove_all(capture_);
  }

  /// Runs `lipsync args…` in dir_; stdin is /dev/null unless `options` name a file.
  RunResult run(std::vector<std::string> args, const RunOptions& options = {}) const {
    args.insert(args.begin(), LIPSYNC_CLI_BINARY);
    return run_program(std::move(args), dir_, capture_, options);
  }

  /// The names in dir_ (or in `directory`), sorted.
  std::vector<std::string> listing() const { return listing(dir_); }
  static std::vector<std::string> listing(const std::filesystem::path& directory) {
    std::vector<std::string> names;
    for (const auto& entry : std::filesystem::directory_iterator(directory))
      names.push_back(entry.path().filename().string());
    std::sort(names.begin(), names.end());
    return names;
  }

  std::filesystem::path dir_;      ///< the command's working directory: holds only what it wrote
  std::filesystem::path capture_;  ///< its stdout and stderr files
};

}  // namespace lipsync::testing
