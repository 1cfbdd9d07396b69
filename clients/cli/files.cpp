// Reading inputs and writing outputs atomically (see files.hpp).
//
// POSIX calls are used where the reason for a failure matters: errno names it
// ("No such file or directory", "Is a directory", "Permission denied"), which
// iostreams do not report. While a temporary output file exists its name is
// also kept in a static buffer, and SIGINT/SIGTERM/SIGHUP remove it before
// the process dies with the signal's default action.
#include "files.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <csignal>
#include <cstring>
#include <filesystem>
#include <iostream>

#include "cli_error.hpp"

namespace lipsync::cli {
namespace {

std::string in_quotes(std::string_view text) { return "'" + std::string(text) + "'"; }

std::string reason(int error) { return std::strerror(error); }

// The temporary file a signal handler must remove; empty when there is none.
char g_temp_path[4096] = {};
std::atomic<bool> g_temp_active{false};

extern "C" void remove_temp_and_die(int signal_number) {
  if (g_temp_active.load()) ::unlink(g_temp_path);
  std::signal(signal_number, SIG_DFL);
  std::raise(signal_number);
}

void install_signal_handlers() {
  static const bool kInstalled = [] {
    for (const int signal_number : {SIGINT, SIGTERM, SIGHUP}) {
      if (std::signal(signal_number, remove_temp_and_die) == SIG_IGN) std::signal(signal_number, SIG_IGN);
    }
    return true;
  }();
  (void)kInstalled;
}

}  // namespace

std::string read_file(const std::string& path) {
  const bool from_stdin = path == "-";
  const std::string name = from_stdin ? std::string(kStdinName) : in_quotes(path);
  const int fd = from_stdin ? STDIN_FILENO : ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) throw FileError("cannot read " + name + ": " + reason(errno));
  std::string content;
  char buffer[64 * 1024];
  for (;;) {
    const ssize_t count = ::read(fd, buffer, sizeof buffer);
    if (count == 0) break;
    if (count < 0) {
      if (errno == EINTR) continue;
      const int error = errno;
      if (!from_stdin) ::close(fd);
      throw FileError("cannot read " + name + ": " + reason(error));
    }
    content.append(buffer, static_cast<std::size_t>(count));
  }
  if (!from_stdin) ::close(fd);
  return content;
}

AtomicOutputFile::AtomicOutputFile(std::string path) : path_(std::move(path)) {
  install_signal_handlers();
  struct stat info {};
  if (::stat(path_.c_str(), &info) == 0 && S_ISDIR(info.st_mode)) {
    throw FileError("cannot write " + in_quotes(path_) + ": it is a directory");
  }
  if (::stat(path_.c_str(), &info) == 0 && !S_ISREG(info.st_mode)) {
    stream_.open(path_, std::ios::binary);
    if (!stream_) throw FileError("cannot write " + in_quotes(path_) + ": " + reason(errno));
    errno = 0;
    return;
  }
  const std::filesystem::path target(path_);
  const std::filesystem::path directory = target.has_parent_path() ? target.parent_path() : ".";
  const std::string stem = "." + target.filename().string() + ".tmp-" + std::to_string(::getpid());
  // O_EXCL with mode 0666 (less the umask): the final file gets ordinary permissions.
  for (int attempt = 0;; ++attempt) {
    temp_path_ = (directory / (stem + "-" + std::to_string(attempt))).string();
    const int fd = ::open(temp_path_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
    if (fd >= 0) {
      ::close(fd);
      break;
    }
    if (errno != EEXIST || attempt >= 100) {
      throw FileError("cannot create " + in_quotes(path_) + ": " + reason(errno));
    }
  }
  if (temp_path_.size() < sizeof g_temp_path) {
    std::memcpy(g_temp_path, temp_path_.c_str(), temp_path_.size() + 1);
    g_temp_active.store(true);
  }
  stream_.open(temp_path_, std::ios::binary | std::ios::trunc);
  if (!stream_) {
    const int error = errno;
    discard();
    throw FileError("cannot create " + in_quotes(path_) + ": " + reason(error));
  }
  errno = 0;  // so that commit() reports the errno of a failed write, not an older one
}

AtomicOutputFile::~AtomicOutputFile() {
  if (!done_) discard();
}

void AtomicOutputFile::commit() {
  stream_.flush();
  const bool written = static_cast<bool>(stream_);
  stream_.close();
  if (!written || stream_.fail()) {
    discard();
    throw FileError("cannot write " + in_quotes(path_) + ": " + reason(errno != 0 ? errno : EIO));
  }
  if (temp_path_.empty()) {  // written directly
    done_ = true;
    return;
  }
  if (std::rename(temp_path_.c_str(), path_.c_str()) != 0) {
    const int error = errno;
    discard();
    throw FileError("cannot write " + in_quotes(path_) + ": " + reason(error));
  }
  g_temp_active.store(false);
  done_ = true;
}

void AtomicOutputFile::discard() noexcept {
  g_temp_active.store(false);
  if (stream_.is_open()) stream_.close();
  if (!temp_path_.empty()) ::unlink(temp_path_.c_str());
  done_ = true;
}

void write_to_output(const std::string& output, std::string_view what,
                     const std::function<void(std::ostream&)>& write) {
  if (output == "-") {
    write(std::cout);
    std::cout.flush();
    if (!std::cout) throw FileError("cannot write the " + std::string(what) + " to standard output");
    return;
  }
  AtomicOutputFile file(output);
  write(file.stream());
  file.commit();
}

}  // namespace lipsync::cli
