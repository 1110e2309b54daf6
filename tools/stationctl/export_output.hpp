#pragma once
// Where `stationctl export` writes its bytes (issue #19, item 1: an export must never destroy what
// is at the path it is given):
//  * no path: standard output;
//  * a path naming a regular file, or nothing yet: a temporary file beside it (".NAME.XXXXXX", the
//    existing file's permission bits, else 0666 less the umask), written, flushed to disk and only
//    then renamed over the path — a failed or interrupted export leaves the old file as it was;
//  * a symbolic link is followed on purpose: its final target is what gets written, by these same
//    rules, and the link stays a link (a dangling link's target is created);
//  * a path that exists and is not a regular file — a character or block device (/dev/null,
//    /dev/full), a named pipe — is written directly, as a shell redirection would (a pipe's reader
//    gets the rows); /dev/stdout, /dev/stderr, /dev/fd/N and /proc/self/fd/N write to the
//    process's own descriptor (the shell's redirection, its offset and append mode, hold);
//  * a directory or a socket is refused before anything is read;
//  * every error names the user's path (never the temporary file) and the system's reason.
#include <memory>
#include <ostream>
#include <stdexcept>
#include <string>
#include <string_view>

namespace imucal::tools::stationctl {

/// Why the output cannot be opened or written; what() names the user's path and the reason.
class ExportOutputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class ExportOutput {
 public:
  /// Opens the output (an empty path: standard output). Throws ExportOutputError.
  explicit ExportOutput(const std::string& path);
  /// An output not committed (an export that failed) is abandoned: the temporary file is removed.
  ~ExportOutput();
  ExportOutput(const ExportOutput&) = delete;
  ExportOutput& operator=(const ExportOutput&) = delete;

  /// The bytes so far go through this stream too (db::history::export_history writes to a
  /// std::ostream).
  std::ostream& stream();
  /// Writes `bytes`; throws ExportOutputError on a write error.
  void write(std::string_view bytes);
  /// Throws ExportOutputError, naming the reason, if a write through stream() has failed (for a
  /// writer that reports a failed stream in words of its own).
  void check() const;
  /// Flushes everything and, for a regular file, makes it the path's content (rename). Throws
  /// ExportOutputError.
  void commit();

  /// How the path is written (for tests and messages).
  enum class Mode { kStdout, kReplaceFile, kDirect };
  Mode mode() const { return mode_; }

 private:
  class FdBuf;
  [[noreturn]] void fail(int err) const;

  std::string path_;    ///< as the user gave it
  std::string target_;  ///< the file that gets replaced (links followed), kReplaceFile only
  std::string tmp_;     ///< the temporary file, kReplaceFile only
  Mode mode_ = Mode::kStdout;
  int fd_ = -1;
  bool committed_ = false;
  std::unique_ptr<FdBuf> buf_;
  std::unique_ptr<std::ostream> stream_;
};

}  // namespace imucal::tools::stationctl
