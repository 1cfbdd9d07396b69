// File input and output for the command line. The core never touches files;
// this is where bytes come from and go to.
//
// Output is all-or-nothing: a track is written to a temporary file next to
// the destination and renamed over it only once everything was written and
// flushed, so a failure (or Ctrl-C) never leaves a partial or truncated track
// where the user expects one, and never destroys an older file of that name.
#pragma once

#include <fstream>
#include <functional>
#include <ostream>
#include <string>
#include <string_view>

namespace lipsync::cli {

/// Name used for standard input in messages.
inline constexpr std::string_view kStdinName = "<stdin>";

/// The bytes of `path`, or of standard input for "-". Throws FileError naming
/// the file and the reason (missing, unreadable, a directory).
std::string read_file(const std::string& path);

/// A file that appears at `path` only when commit() succeeds. Where `path` names something that is
/// not a regular file (/dev/null, a named pipe, a terminal) it is written directly: renaming a
/// file over it would replace the device.
class AtomicOutputFile {
 public:
  /// Creates the temporary file in the directory of `path` (or opens `path` itself, as above).
  /// Throws FileError.
  explicit AtomicOutputFile(std::string path);
  ~AtomicOutputFile();
  AtomicOutputFile(const AtomicOutputFile&) = delete;
  AtomicOutputFile& operator=(const AtomicOutputFile&) = delete;

  std::ostream& stream() { return stream_; }
  /// Flushes, closes and renames onto `path`. Throws FileError (and removes
  /// the temporary file) if any write failed.
  void commit();

 private:
  void discard() noexcept;

  std::string path_;
  std::string temp_path_;  // empty when `path` is written directly
  std::ofstream stream_;
  bool done_ = false;
};

/// Writes what `write` puts on its stream to `output`: for "-" to standard output, flushed (a
/// failed write is FileError "cannot write the WHAT to standard output", WHAT being `what`); for
/// a path all or nothing through an AtomicOutputFile.
void write_to_output(const std::string& output, std::string_view what, const std::function<void(std::ostream&)>& write);

}  // namespace lipsync::cli
