#pragma once
// The candump log format ("compact CAN frame logfile"), as can-utils 2020.11 `candump -l` writes
// and `canplayer`, `log2asc`, python-can's CanutilsLogReader and SavvyCAN read it. One frame per
// line:
//   (SSSSSSSSSS.UUUUUU) IFACE FRAME
//   seconds zero-padded to 10 digits, microseconds to 6 (CLOCK_REALTIME receive time), IFACE the
//   interface name, FRAME as can-utils' lib.c prints it:
//     standard id   3 upper-case hex digits   "123#DEADBEEF"
//     extended id   8 hex digits (no flag)     "12345678#00"
//     error frame   8 hex digits incl. 0x20000000 (CAN_ERR_FLAG), 8 data bytes
//     remote frame  "123#R" or "123#R4" (the DLC digit only when non-zero)
//     data          2 upper-case hex digits per byte, no separator, 0..8 bytes
// The run archive's capture.log is written in this format (ARCHITECTURE §5).
//
// The parser also accepts what other writers add: any number of fraction digits (1-9) in the
// timestamp, '.' separators between data bytes, and a trailing " R" / " T" (rx/tx) token as
// python-can's CanutilsLogWriter writes. CAN FD lines ("ID##F...") are refused: the station uses
// classic CAN only.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <string_view>

#include "drivers/imu/can_frame.hpp"

namespace imucal::drivers::imu {

/// A malformed log; what() = "<file>:<line>: <reason>" (line 0 = the file as a whole).
class CandumpParseError : public std::runtime_error {
 public:
  CandumpParseError(std::string file, std::size_t line, const std::string& reason);
  const std::string& file() const { return file_; }
  std::size_t line() const { return line_; }

 private:
  std::string file_;
  std::size_t line_;
};

struct CandumpRecord {
  ReceivedFrame frame;    ///< rx_time_ns = the logged time (microsecond resolution in candump logs)
  std::string interface;  ///< the logged interface name
};

/// One log line without the trailing newline. Throws std::invalid_argument for a negative time,
/// an empty or space-containing interface name, or a frame longer than 8 bytes.
std::string format_candump_line(const ReceivedFrame& frame, std::string_view interface);

/// Parses one line (without the newline). Throws std::invalid_argument naming what is wrong.
CandumpRecord parse_candump_line(std::string_view line);

/// Reads a candump log line by line.
class CandumpReader {
 public:
  /// Throws CandumpParseError(path, 0, ...) if the file cannot be opened.
  explicit CandumpReader(const std::string& path);
  ~CandumpReader();
  CandumpReader(const CandumpReader&) = delete;
  CandumpReader& operator=(const CandumpReader&) = delete;

  /// The next record; false at the end of the file. Empty lines are skipped. A malformed line throws
  /// CandumpParseError with its line number — except a last line without its newline (a writer
  /// killed mid-line), which is skipped and counted in truncated_lines().
  bool next(CandumpRecord& record);

  int fd() const;
  const std::string& path() const { return path_; }
  std::size_t line_number() const { return line_no_; }
  uint64_t truncated_lines() const { return truncated_; }

 private:
  std::string path_;
  std::FILE* file_ = nullptr;
  std::string line_;
  std::size_t line_no_ = 0;
  uint64_t truncated_ = 0;
};

/// Writes a candump log (the raw capture archived per run).
class CandumpWriter {
 public:
  /// Creates (or truncates, or with append=true extends) the file; throws std::runtime_error naming
  /// the path and the system error.
  explicit CandumpWriter(const std::string& path, bool append = false);
  ~CandumpWriter();  ///< flushes; errors at that point are ignored (call close() to see them)
  CandumpWriter(const CandumpWriter&) = delete;
  CandumpWriter& operator=(const CandumpWriter&) = delete;

  void write(const ReceivedFrame& frame, std::string_view interface);
  /// Hands the buffered lines to the kernel.
  void flush();
  /// flush() + fdatasync(): the lines written so far survive a crash or power loss.
  void sync();
  /// sync() and close; throws on any error.
  void close();

  uint64_t frames_written() const { return frames_; }
  const std::string& path() const { return path_; }

 private:
  std::string path_;
  int fd_ = -1;
  std::string buffer_;
  uint64_t frames_ = 0;
};

}  // namespace imucal::drivers::imu
