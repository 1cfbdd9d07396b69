// Helpers for tests that run the project's real binaries: temporary
// directories, whole-file reads and writes, and child processes with their
// standard streams redirected to files (no shell in between): one run to
// completion, or one left running (a server) while the test talks to it.
#pragma once

#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace lipsync::testing {

inline std::string read_text(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

inline void write_text(const std::filesystem::path& path, std::string_view text) {
  std::ofstream(path, std::ios::binary) << text;
}

/// A fresh directory under the system temporary directory, named `prefix` + random.
inline std::filesystem::path make_temp_dir(const std::string& prefix) {
  std::string pattern = (std::filesystem::temp_directory_path() / (prefix + "XXXXXX")).string();
  if (::mkdtemp(pattern.data()) == nullptr) throw std::runtime_error("mkdtemp failed for " + pattern);
  return pattern;
}

struct RunResult {
  int status = -1;  ///< exit code, 128 + signal when killed, -1 when it could not be started
  std::string out;
  std::string err;
};

struct RunOptions {
  std::optional<std::filesystem::path> stdin_file;  ///< default /dev/null
  std::optional<std::string> path_env;              ///< replaces PATH in the child
};

/// A running child: `argv` (argv[0] a path to the program) started in `cwd`
/// with stdin from a file (default /dev/null) and stdout and stderr written to
/// `out_path` and `err_path`. Killed (SIGKILL) if still running when destroyed.
class ChildProcess {
 public:
  ChildProcess(std::vector<std::string> argv_text, const std::filesystem::path& cwd,
               const std::filesystem::path& out_path, const std::filesystem::path& err_path,
               const RunOptions& options = {}) {
    std::vector<char*> argv;
    for (std::string& arg : argv_text) argv.push_back(arg.data());
    argv.push_back(nullptr);
    pid_ = ::fork();
    if (pid_ == 0) {
      const std::string in_path = options.stdin_file ? options.stdin_file->string() : "/dev/null";
      const int in = ::open(in_path.c_str(), O_RDONLY);
      const int out = ::open(out_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      const int err = ::open(err_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      if (in < 0 || out < 0 || err < 0 || ::chdir(cwd.c_str()) != 0) ::_exit(126);
      ::dup2(in, STDIN_FILENO);
      ::dup2(out, STDOUT_FILENO);
      ::dup2(err, STDERR_FILENO);
      if (options.path_env) ::setenv("PATH", options.path_env->c_str(), 1);
      ::execv(argv_text[0].c_str(), argv.data());
      ::_exit(127);
    }
  }
  ChildProcess(const ChildProcess&) = delete;
  ChildProcess& operator=(const ChildProcess&) = delete;
  ~ChildProcess() {
    if (pid_ > 0 && !waited_) {
      ::kill(pid_, SIGKILL);
      wait();
    }
  }

  /// The exit code, 128 + signal when killed, -1 when it could not be started.
  int wait() {
    int status = 0;
    if (pid_ <= 0 || ::waitpid(pid_, &status, 0) != pid_) return -1;
    waited_ = true;
    return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  }
  void terminate() { ::kill(pid_, SIGTERM); }
  void signal(int number) { ::kill(pid_, number); }
  pid_t pid() const { return pid_; }

 private:
  pid_t pid_ = -1;
  bool waited_ = false;
};

/// The HOST:PORT of a lipsyncd whose stdout goes to `out`, from its line "lipsyncd listening on
/// HOST:PORT" (or another server's line that starts with `prefix`); "" if that line has not come
/// within 10 s.
inline std::string wait_for_listening_address(const std::filesystem::path& out,
                                              const std::string& prefix = "lipsyncd listening on ") {
  for (int i = 0; i < 500; ++i) {
    const std::string text = read_text(out);
    const auto at = text.find(prefix);
    const auto end = at == std::string::npos ? at : text.find('\n', at);
    if (end != std::string::npos) return text.substr(at + prefix.size(), end - at - prefix.size());
    ::usleep(20'000);
  }
  return "";
}

/// Whether `text` appears in the file `path` within `timeout` (polled every 20 ms).
inline bool wait_for_text(const std::filesystem::path& path, std::string_view text,
                          std::chrono::milliseconds timeout = std::chrono::seconds(10)) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (read_text(path).find(text) == std::string::npos) {
    if (std::chrono::steady_clock::now() >= deadline) return false;
    ::usleep(20'000);
  }
  return true;
}

/// Runs `argv` (argv[0] a path to the program) in `cwd` and waits for it;
/// stdout and stderr go through files in `capture`.
inline RunResult run_program(std::vector<std::string> argv_text, const std::filesystem::path& cwd,
                             const std::filesystem::path& capture, const RunOptions& options = {}) {
  const std::filesystem::path out_path = capture / "stdout";
  const std::filesystem::path err_path = capture / "stderr";
  RunResult result;
  result.status = ChildProcess(std::move(argv_text), cwd, out_path, err_path, options).wait();
  if (result.status < 0) return result;
  result.out = read_text(out_path);
  result.err = read_text(err_path);
  return result;
}

}  // namespace lipsync::testing
