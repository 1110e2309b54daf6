#pragma once
// Start-up recovery of stationd (issue #3 item 4: "an interrupted run is marked interrupted, its
// raw data kept and reprocessable; never silently resumed").
//
// A daemon that died (kill -9, power cut, crash) leaves the table possibly moving and runs in a
// live state (preparing, running, calibrating) in the database. Before it accepts any request the
// new daemon:
//   1. commands the table to a safe stop if it is reachable (a short connect attempt; an
//   unreachable
//      table is logged, not fatal: it may be switched off);
//   2. for every live run: cuts its archive to whole, matching rows (recover_archive, which marks
//      run.toml [capture] complete = false and leaves capture.log as raw data; a finished archive
//      is left untouched), computes its SHA-256, and stores the run as interrupted with a reason
//      that says in which state it was found and what was kept — together with the recounted
//      capture counters. A run killed before its archive existed is interrupted with a reason
//      saying so. The run is never resumed: `reprocess RUN_ID` recalibrates the kept archive.
#include <string>
#include <vector>

#include "db/history/repository.hpp"
#include "db/history/sqlite_repository.hpp"
#include "station/config/config.hpp"

namespace imucal::station::run {
using namespace station::config;

struct RecoveredRun {
  db::history::RunId run_id = 0;
  db::history::RunState found_in = db::history::RunState::kPreparing;
  std::string archive_path;  ///< "" if the run had no archive yet
  uint64_t rows_kept = 0;
  std::string archive_sha256;
  std::string reason;  ///< as stored
};

struct RecoveryReport {
  bool table_reached = false;  ///< the safe stop was delivered
  std::string table_note;      ///< why not, if not
  std::vector<RecoveredRun> runs;
};

/// Safe stop of the table (skipped if stop_table is false, e.g. for tests without a table).
/// Throws only if the repository fails; a damaged archive is reported in the run's reason.
RecoveryReport recover_at_startup(const StationConfig& config, db::history::Repository& repository,
                                  bool stop_table = true);

/// The highest run id among the run archives in `data_dir`/runs (directories `<id>-<serial>`),
/// 0 if there are none.
db::history::RunId highest_archived_run_id(const std::string& data_dir);

/// Start-up: new runs are numbered after every archive in the data directory. A database that was
/// replaced (a new, empty one) or restored from an older copy would issue those ids again: the
/// station would refuse to write a run's archive over the old one (the run failed), and the fleet
/// store would refuse the run as another under a known local id. Returns the id the numbering now
/// continues after, 0 if it already did (logged as a warning when it moves).
db::history::RunId continue_run_ids_after_archives(const StationConfig& config,
                                                   db::history::SqliteRepository& repository);

}  // namespace imucal::station::run
