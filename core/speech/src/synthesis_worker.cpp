// The synthesis worker process (synthesis_worker.hpp): one process per synthesis.
//
// espeak-ng's output depends on what the process spoke before: its wave
// generator keeps state across calls in function-level statics (the pitch
// flutter index, the automatic gain, the phase of the glottal cycle), so the
// same text spoken twice in one process gives audio a few samples apart, with
// phoneme times shifted to match. espeak_Terminate does not reset them, and a
// second espeak_Initialize after it hangs (espeak-ng 1.51). So every synthesis
// runs in a process of its own, in which espeak-ng starts fresh: the audio and
// the timings depend on the text and the options alone, whichever process asks
// and whatever it spoke before (`lipsync say`, a long-running lipsyncd, a test).
// The asking process never initialises espeak-ng itself.
//
// That process is the running program started again (posix_spawn of
// /proc/self/exe), not a fork that goes on without exec: the asker is often
// multi-threaded (a gRPC server), and a forked child may only make
// async-signal-safe calls, for any other thread may have held a lock (the
// allocator's, stdio's, the sanitizers') at the moment of the fork. A forked
// child that synthesised hung on such a lock under AddressSanitizer. The new
// process knows it is a synthesis worker by LIPSYNC_ESPEAK_WORKER=1 in its
// environment: a constructor of this file, which every program that can ask
// for a synthesis links (synthesize() calls synthesize_in_worker(), so the linker
// takes this file from the static library), sees it before main, reads the request
// from its standard input (a memfd the asker wrote), writes the answer to its
// standard output (a pipe) and _exits, so none of the program's own start-up runs.
// Starting a process costs a few milliseconds beside the synthesis's tens.
// The bytes of the request and the answer are synthesis_wire.cpp's.
#include "synthesis_worker.hpp"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/mman.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "espeak_synthesis.hpp"
#include "lipsync/error.hpp"
#include "synthesis_wire.hpp"

namespace lipsync::speech::detail {
namespace {

constexpr const char* kWorkerVariable = "LIPSYNC_ESPEAK_WORKER";

/// Writes all of `bytes` to `fd`; false on an error.
bool write_all(int fd, std::string_view bytes) {
  while (!bytes.empty()) {
    const ssize_t n = ::write(fd, bytes.data(), bytes.size());
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    bytes.remove_prefix(static_cast<std::size_t>(n));
  }
  return true;
}

// --- in the worker

/// Standard input to its end.
std::string read_request() {
  std::string request;
  char buffer[65536];
  for (;;) {
    const ssize_t n = ::read(STDIN_FILENO, buffer, sizeof buffer);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0)
      throw std::runtime_error("the synthesis worker cannot read its request: " + std::string(std::strerror(errno)));
    if (n == 0) break;
    request.append(buffer, static_cast<std::size_t>(n));
  }
  return request;
}

/// Reads the request from standard input, synthesises, writes the encoded answer (the result or
/// the error) to standard output, and _exits.
[[noreturn]] void serve_one_synthesis() {
  std::string out;
  try {
    const SynthesisRequest request = decode_request(read_request());
    out = encode_answer(synthesize_with_espeak(request.text, request.options));
  } catch (const InputError& error) {
    out = encode_input_error_answer(error.message());
  } catch (const std::exception& error) {
    out = encode_other_error_answer(error.what());
  }
  ::_exit(write_all(STDOUT_FILENO, out) ? 0 : 1);
}

/// Before main: a process started as a synthesis worker does only that.
[[gnu::constructor]] void become_a_synthesis_worker_if_asked() {
  const char* worker = std::getenv(kWorkerVariable);
  if (worker != nullptr && std::string_view(worker) == "1") serve_one_synthesis();
}

// --- in the asking process

/// How long a worker may take before it is killed: generous (espeak-ng speaks a
/// 4,096-byte text in about a second), so that only a hung worker meets it.
std::chrono::milliseconds worker_deadline(std::size_t text_bytes) {
  return std::chrono::milliseconds(30'000 + 10 * static_cast<std::int64_t>(text_bytes));
}

/// Closes a file descriptor when it goes out of scope.
struct FileDescriptor {
  int fd = -1;
  FileDescriptor() = default;
  explicit FileDescriptor(int fd_in) : fd(fd_in) {}
  FileDescriptor(FileDescriptor&& other) noexcept : fd(std::exchange(other.fd, -1)) {}
  FileDescriptor(const FileDescriptor&) = delete;
  FileDescriptor& operator=(const FileDescriptor&) = delete;
  ~FileDescriptor() { reset(); }
  void reset() {
    if (fd >= 0) ::close(fd);
    fd = -1;
  }
};

std::runtime_error system_error(const std::string& what) {
  return std::runtime_error("espeak-ng: " + what + ": " + std::strerror(errno));
}

/// The request in a memfd: written whole before the worker starts, so the asker never
/// blocks on (or gets SIGPIPE from) a worker that dies without reading.
FileDescriptor request_file(std::string_view text, const SynthesisOptions& options) {
  FileDescriptor request(::memfd_create("lipsync-espeak-request", MFD_CLOEXEC));
  if (request.fd < 0) throw system_error("cannot create the synthesis request");
  if (!write_all(request.fd, encode_request(text, options)) || ::lseek(request.fd, 0, SEEK_SET) != 0) {
    throw system_error("cannot write the synthesis request");
  }
  return request;
}

/// This process's environment with LIPSYNC_ESPEAK_WORKER=1 in place of any value it had.
std::vector<std::string> worker_environment() {
  std::vector<std::string> environment;
  for (char** variable = environ; *variable != nullptr; ++variable) {
    if (!std::string_view(*variable).starts_with(std::string(kWorkerVariable) + "="))
      environment.emplace_back(*variable);
  }
  environment.push_back(std::string(kWorkerVariable) + "=1");
  return environment;
}

/// Starts /proc/self/exe as a worker with `request_fd` as its standard input and `answer_fd` as its
/// standard output; its process id.
pid_t start_worker(int request_fd, int answer_fd) {
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, request_fd, STDIN_FILENO);
  posix_spawn_file_actions_adddup2(&actions, answer_fd, STDOUT_FILENO);
  std::vector<std::string> environment = worker_environment();
  std::vector<char*> envp;
  envp.reserve(environment.size() + 1);
  for (std::string& variable : environment) envp.push_back(variable.data());
  envp.push_back(nullptr);
  char name[] = "lipsync-espeak-worker";
  char* argv[] = {name, nullptr};
  pid_t pid = 0;
  const int spawned = ::posix_spawn(&pid, "/proc/self/exe", &actions, nullptr, argv, envp.data());
  posix_spawn_file_actions_destroy(&actions);
  if (spawned != 0) {
    errno = spawned;
    throw system_error("cannot start the synthesis process");
  }
  return pid;
}

/// What came back from a worker by its deadline.
struct WorkerAnswer {
  std::string bytes;
  bool timed_out = false;
  int read_error = 0;  // errno of a failed read, else 0
};

/// Reads `fd` to its end or until `deadline`, whichever comes first.
WorkerAnswer read_answer(int fd, std::chrono::steady_clock::time_point deadline) {
  WorkerAnswer answer;
  char buffer[65536];
  for (;;) {
    const auto left =
        std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0) {
      answer.timed_out = true;
      break;
    }
    pollfd readable{fd, POLLIN, 0};
    const int ready = ::poll(&readable, 1, static_cast<int>(left.count()));
    if (ready < 0 && errno == EINTR) continue;
    if (ready == 0) continue;  // the deadline is checked above
    const ssize_t n = ready < 0 ? -1 : ::read(fd, buffer, sizeof buffer);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) answer.read_error = errno;  // the worker is killed: nothing more can come
    if (n <= 0) break;
    answer.bytes.append(buffer, static_cast<std::size_t>(n));
  }
  return answer;
}

}  // namespace

Synthesis synthesize_in_worker(std::string_view text, const SynthesisOptions& options) {
  FileDescriptor request = request_file(text, options);
  int fds[2];
  if (::pipe2(fds, O_CLOEXEC) != 0) throw system_error("cannot create a pipe");
  FileDescriptor answer_read(fds[0]);
  FileDescriptor answer_write(fds[1]);
  const pid_t pid = start_worker(request.fd, answer_write.fd);
  answer_write.reset();
  request.reset();

  const WorkerAnswer answer =
      read_answer(answer_read.fd, std::chrono::steady_clock::now() + worker_deadline(text.size()));
  if (answer.timed_out || answer.read_error != 0) ::kill(pid, SIGKILL);
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  if (answer.timed_out) {
    throw std::runtime_error("espeak-ng: the synthesis process did not answer within " +
                             std::to_string(worker_deadline(text.size()).count() / 1000) + " s and was killed");
  }
  if (answer.read_error != 0) {
    errno = answer.read_error;
    throw system_error("cannot read the synthesis process's answer");
  }
  if (WIFSIGNALED(status)) {
    throw std::runtime_error("espeak-ng: the synthesis process died with signal " + std::to_string(WTERMSIG(status)));
  }
  if (answer.bytes.empty()) {
    throw std::runtime_error("espeak-ng: the synthesis process ended (exit status " +
                             std::to_string(WEXITSTATUS(status)) + ") without an answer");
  }
  return decode_answer(answer.bytes);
}

}  // namespace lipsync::speech::detail
