#pragma once
// `stationctl import`'s steps before a run is recorded (issue #19 item 3): the archive's own times,
// the station's copy staged under its runs directory, and the refusal of an archive the history
// already holds. Nothing here touches the repository's write side: a refused import leaves no run
// and no directory behind.
#include <optional>
#include <string>

#include "db/archive/run_archive.hpp"
#include "db/history/repository.hpp"

namespace imucal::station::run {

/// When the imported run was recorded: run.toml's start_time, and its end_time when it is later
/// than the start, else the start plus the IMU data's span. Without a start_time the import time
/// stands in (`recorded` false, and the origin says so).
struct RecordedTimes {
  db::history::TimestampMs started_at_ms = 0;
  db::history::TimestampMs ended_at_ms = 0;
  bool recorded = false;
};
RecordedTimes recorded_times(const db::archive::RunArchive& ar, db::history::TimestampMs import_ms);

/// The run's origin text: "imported from DIR on 2026-11-26T15:20:00.000Z" (+ a note when the
/// archive had no start time).
std::string import_origin(const std::string& dir, db::history::TimestampMs import_ms,
                          const RecordedTimes& times);

/// The station's copy of an imported archive, written under `runs_dir` before the run exists and
/// renamed into place once it does; removed on destruction unless moved.
class StagedImport {
 public:
  /// Writes `ar` to a fresh hidden directory in runs_dir; digests of the source directory and of
  /// the copy (station/run/archive_writer.hpp archive_digest). Throws std::runtime_error naming the
  /// directory on any I/O error (nothing is left behind).
  StagedImport(const std::string& source_dir, const db::archive::RunArchive& ar,
               const std::string& runs_dir);
  ~StagedImport();
  StagedImport(const StagedImport&) = delete;
  StagedImport& operator=(const StagedImport&) = delete;

  const std::string& source_sha256() const { return source_sha256_; }
  const std::string& copy_sha256() const { return copy_sha256_; }
  /// Renames the copy to `dest` (the run's archive directory); throws std::runtime_error.
  void move_to(const std::string& dest);

 private:
  std::string staged_;
  std::string source_sha256_, copy_sha256_;
};

/// The message refusing an archive already in the history (its SHA-256, source or copy, stored
/// with a run), naming that run, its serial, state and origin; nullopt when it is new.
std::optional<std::string> duplicate_import(const db::history::Repository& repo,
                                            const StagedImport& staged);

}  // namespace imucal::station::run
