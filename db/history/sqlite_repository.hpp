#pragma once
// The embedded default backend of the calibration history: one SQLite file (ARCHITECTURE §2, §10).
//
// Every connection: journal_mode=WAL (readers never block the writer and vice versa),
// synchronous=FULL (a commit is on disk before the call returns: a power cut after create_run()
// returned cannot lose the run), busy_timeout, foreign_keys=ON. Every statement is prepared with
// bound values (no SQL is ever built from values). Every write, and every multi-row write in
// particular, is one transaction (BEGIN IMMEDIATE, so two writers queue on busy_timeout instead of
// deadlocking on a lock upgrade); every read method reads one consistent snapshot.
//
// Read-only mode (SqliteOptions::read_only) opens the file with SQLITE_OPEN_READONLY for QA reads
// while the daemon is down or running: it never creates, migrates or writes; a write method throws
// db::history::ReadOnly. It sees every transaction committed before each read method starts.
//
// Thread safety: one SqliteRepository may be shared by threads (calls are serialised by an
// internal mutex). Separate processes each open their own.
#include <functional>
#include <memory>
#include <string>

#include "db/history/outbox.hpp"
#include "db/history/repository.hpp"

namespace imucal::db::history {

/// SQLite's memory, bounded in one place (issue #22 item 4). Measured before (soak of 200 runs, the
/// daemon printing sqlite3_status64 after each run): the page cache of the daemon's connection
/// followed the growing database, +5.9 kB a run (1.4 pages of 4 KiB with their headers), and each
/// streamed export's connection filled a cache of its own (SQLite's memory 1.6 MB when a sample
/// fell during one); nothing else of SQLite's or of the rest of the heap grew. The daemon's RSS
/// crept 10.6 kB a run (runs 101-200) and would have stopped only at SQLite's built-in default of
/// 2000 KiB a connection (Debian's build; other builds differ), stated nowhere. Now:
///   * every connection (the daemon's, each streamed export's, stationctl's): a page cache of at
///     most kSqlitePageCacheKiB (PRAGMA cache_size = -512: 106 pages of 4 KiB with their headers).
///     In the soak it is full by run 83, then SQLite's memory stays at 0.81 MB (0.46 MB of cache;
///     before: 1.52 MB at run 200 and rising). The write path and a unit's recent history fit; a
///     longer scan reads the rest from the OS page cache (db_history_bench, 100 000 runs: history
///     of a serial 0.38-0.41 ms against 0.35-0.37 ms with 2000 KiB; params, show unchanged);
///   * every connection: no memory-mapped I/O (PRAGMA mmap_size = 0; a build that defaults to mmap
///     would map the database file into the daemon's resident set as the file grows);
///   * stationd: a soft heap limit of kSqliteSoftHeapLimitBytes for all of SQLite in the process
///     (limit_sqlite_process_memory()), a backstop over the daemon's connection and up to 4
///     streamed exports, each with its own cache: past it SQLite recycles cache pages instead of
///     allocating. No hard limit: at the hard limit SQLite fails with SQLITE_NOMEM, and a run's
///     results would not be stored.
inline constexpr int kSqlitePageCacheKiB = 512;
inline constexpr long long kSqliteSoftHeapLimitBytes = 4LL << 20;

/// Sets SQLite's process-wide soft heap limit (kSqliteSoftHeapLimitBytes). Call once, before the
/// first connection opens (stationd's main).
void limit_sqlite_process_memory();

struct SqliteOptions {
  bool read_only = false;  ///< SQLITE_OPEN_READONLY; the file must exist and be at kSchemaVersion
  bool create = true;      ///< read-write: create the file if missing (else NotFound)
  int busy_timeout_ms = 5000;  ///< how long to wait for another writer before db::history::Busy
};

class SqliteRepository final : public Repository {
 public:
  /// Opens (and in read-write mode creates/migrates, db/history/schema.hpp) the database at `path`.
  /// Throws NotFound (no file), IncompatibleSchema (newer or foreign), Corrupt (not a database),
  /// Busy, IoError — each naming the path.
  explicit SqliteRepository(const std::string& path, const SqliteOptions& options = {});
  ~SqliteRepository() override;
  SqliteRepository(const SqliteRepository&) = delete;
  SqliteRepository& operator=(const SqliteRepository&) = delete;

  RunId create_run(const NewRun& run) override;
  void update_run_state(RunId run_id, RunState state, const std::string& reason = {}) override;
  void finish_run(RunId run_id, const RunCompletion& completion) override;
  void store_calibration(RunId run_id, const CalibrationRecord& calibration) override;
  void store_crosscheck(RunId run_id, const CrosscheckRecord& crosscheck) override;
  void set_diagnosis(RunId run_id, const std::string& diagnosis_json) override;
  std::vector<RunId> mark_interrupted_runs(TimestampMs now_ms) override;
  std::vector<RunRecord> history(const std::string& serial, std::size_t limit = 0) const override;
  std::size_t run_count(const std::string& serial) const override;
  std::vector<RunRecord> recent_runs(std::size_t limit) const override;
  std::size_t total_run_count() const override;
  /// The highest run id this database has issued (0 for none): new runs are numbered after it.
  RunId highest_run_id_issued() const;
  /// New runs are numbered after `id` from now on, unless they already were: for a station whose
  /// data directory holds archives of runs this database does not know (it was replaced, or
  /// restored from an older copy), so that their ids, their archive directories' names and the
  /// fleet store's copies of them are never issued again. Returns whether the numbering moved.
  /// ReadOnly on a read-only repository.
  bool continue_run_ids_after(RunId id);
  RunDetails show(RunId run_id) const override;
  ActiveCalibration active_params(const std::string& serial) const override;
  void export_rows(const ExportFilter& filter,
                   const std::function<void(const ExportRow&)>& sink) const override;
  std::vector<RunRecord> runs_in_state(const std::vector<RunState>& states) const override;
  std::vector<RunRecord> runs_with_archive_sha256(const std::string& sha256) const override;
  void promote(RunId run_id, const std::string& by, const std::string& reason,
               TimestampMs at_ms) override;

  /// Run `body` (which calls write methods of this repository) as one transaction: all of its
  /// writes commit together or, if it throws, none does (the exception propagates). Nested
  /// calls and the write methods inside use savepoints. For bulk imports and for callers that
  /// need several steps to be atomic.
  void transaction(const std::function<void()>& body);

  // ----- the replication outbox (db/history/outbox.hpp)
  // -----------------------------------------------
  /// Turns the outbox on (the station names a fleet database) or off. Turning it on enqueues every
  /// run already stored (change "resync"), so the fleet store receives the station's whole
  /// history; turning it off empties it (turning it on again resends everything).
  void set_outbox_enabled(bool enabled);
  bool outbox_enabled() const;
  /// The oldest `limit` entries, ascending seq.
  std::vector<OutboxEntry> outbox_batch(std::size_t limit) const;
  /// Removes the entries up to and including `seq` (what the fleet store has confirmed).
  void outbox_remove_through(std::int64_t seq);
  std::size_t outbox_length() const;
  /// Runs with ids in `ids` as the fleet store receives them (RunDetails of each, ascending id;
  /// ids that name no run are left out), read in one snapshot.
  std::vector<RunDetails> details_of(const std::vector<RunId>& ids) const;

  /// PRAGMA integrity_check: "ok" or the problems found, one per line.
  std::string integrity_check() const;
  /// PRAGMA user_version of the open database.
  int schema_version() const;
  const std::string& path() const;
  bool read_only() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace imucal::db::history
