#pragma once
// The run archive of ARCHITECTURE §5 (db/archive/FORMAT.md), written while the run goes: run.toml
// at the start, imu.csv / table.csv / capture.log appended row by row and frame by frame, run.toml
// rewritten atomically at the end. Whatever moment the daemon dies, the directory holds a usable
// prefix of the run: recover_archive() cuts it to whole, matching rows and marks it incomplete, and
// db/archive's read_archive() then reads it like any other archive.
//
// Row text uses db/archive's own number formatting (db::archive::append_double: shortest
// round-trip; table angles via db::archive::human_for_si), so what read_archive() returns is
// bit-identical to what was appended. imu.csv has no temp_c column (the archive allows it only when
// every sample has a temperature, which a live stream cannot promise).
//
// Not thread-safe: one owner (station::run::Capture serialises its own use).
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>

#include "calib/core/imu_increment.hpp"
#include "db/archive/run_archive.hpp"
#include "drivers/imu/can_frame.hpp"
#include "drivers/imu/imu_codec.hpp"

namespace imucal::drivers::imu {
class CandumpWriter;
}

namespace imucal::station::run {

class ArchiveWriter {
 public:
  /// Creates `dir` (must not exist or be empty), writes run.toml (end_time empty), opens imu.csv,
  /// table.csv (headers) and capture.log, and makes that skeleton durable (fsync files and
  /// directory). `info.reference` must be table. Throws std::runtime_error naming the path;
  /// on failure nothing it created is left behind.
  ArchiveWriter(const std::string& dir, const db::archive::RunInfo& info);
  /// Flushes what is buffered (errors ignored) and closes; the archive stays as it is (unfinished
  /// archives are for recover_archive).
  ~ArchiveWriter();
  ArchiveWriter(const ArchiveWriter&) = delete;
  ArchiveWriter& operator=(const ArchiveWriter&) = delete;

  /// One imu.csv row and the table.csv row for the same time (inc.t_s must equal table.t_s, be
  /// finite and greater than the previous row's). Angles in table are radians (written as degrees
  /// that read back to the same radians). Throws std::invalid_argument for bad values,
  /// std::logic_error after finish(), std::runtime_error on I/O errors.
  void append_row(const calib::core::ImuIncrement& inc, const calib::core::TableSample& table);
  /// One capture.log line (candump format) with the frame's receive time.
  void append_frame(const drivers::imu::ReceivedFrame& frame, std::string_view interface);
  /// Hands complete lines to the kernel: imu.csv and table.csv in lockstep (both hold the same rows
  /// afterwards), then capture.log. Also done automatically when the buffers grow large.
  void flush();
  /// flush() + fdatasync() of the three files: what was appended survives a power loss.
  void sync();
  /// Ends the archive: sync, close, and run.toml rewritten atomically (temporary file, fsync,
  /// rename, fsync of the directory) from final_info (end time, [capture]). The self-check parse
  /// runs first, so a run.toml the reader would reject is never written. No appends afterwards.
  void finish(const db::archive::RunInfo& final_info);

  const std::string& dir() const { return dir_; }
  uint64_t rows() const { return rows_; }
  uint64_t frames() const;
  uint64_t rest_rows() const { return rest_rows_; }
  bool finished() const { return finished_; }

 private:
  struct File {
    std::string path;
    int fd = -1;
    std::string buf;
    void write_out();  ///< write buf completely, clear it; throws naming path
  };
  void close_files();  ///< no-throw

  std::string dir_;
  File imu_, table_;
  std::unique_ptr<drivers::imu::CandumpWriter> capture_;
  uint64_t rows_ = 0;
  uint64_t rest_rows_ = 0;
  double last_t_s_ = 0.0;
  bool finished_ = false;
};

/// Start-up recovery of an archive a killed daemon left: imu.csv and table.csv cut to their common
/// prefix of complete rows (complete lines that parse, with matching t_s), run.toml rewritten with
/// end_time and [capture] complete = false and the counters it can recount: rows_written and
/// rest_samples from the CSV files, and from capture.log (every frame the capture received is
/// logged) frames_received = frames_logged and the decoder's counters by replaying the log through
/// an ImuFrameDecoder with `decoder`'s options, as the live capture decoded it (samples_filled and
/// rx_overflow cannot be recounted: 0). capture.log is left as it is (raw data). An archive that
/// was finished ([capture] complete = true and the files agree with it) is left untouched.
/// Temporary files of an interrupted atomic rewrite are removed. Returns rows kept. Throws
/// db::archive::ArchiveError if run.toml is missing or unreadable or a CSV header is not the
/// archive's.
uint64_t recover_archive(const std::string& dir, const std::string& end_time_iso,
                         const drivers::imu::DecoderOptions& decoder = {});

/// SHA-256 over the archive files (regular files directly in dir, sorted by name;
/// "name  sha256(file)\n" lines hashed), lower-case hex. Throws std::runtime_error naming the path.
std::string archive_digest(const std::string& dir);

}  // namespace imucal::station::run
