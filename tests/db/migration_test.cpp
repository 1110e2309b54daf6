// Schema versioning (PRAGMA user_version): a fresh file gets the current version and our
// application_id; a newer, foreign or non-database file is refused untouched; reopening is
// idempotent; a migration is applied atomically with its version bump (a failing one leaves the old
// version intact).
#include <gtest/gtest.h>
#include <sqlite3.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <optional>

#include "calib/core/param_set.hpp"
#include "db/history/schema.hpp"
#include "db/history/sqlite_repository.hpp"
#include "tests/db/history_fixtures.hpp"

namespace imucal::db {
using namespace imucal::db::history;
namespace {

using test::expect_throw_message;
using test::TempDir;

constexpr TimestampMs kT0Migration = 1714560000000;

/// A raw connection for inspecting or preparing files around the repository.
class RawDb {
 public:
  explicit RawDb(const std::string& path) {
    if (sqlite3_open(path.c_str(), &db_) != SQLITE_OK) ADD_FAILURE() << "open " << path;
  }
  ~RawDb() { sqlite3_close(db_); }
  sqlite3* get() { return db_; }
  void exec(const std::string& sql) {
    char* err = nullptr;
    if (sqlite3_exec(db_, sql.c_str(), nullptr, nullptr, &err) != SQLITE_OK) {
      ADD_FAILURE() << sql << ": " << (err ? err : "?");
      sqlite3_free(err);
    }
  }
  std::string text(const std::string& sql) {
    sqlite3_stmt* st = nullptr;
    std::string out;
    if (sqlite3_prepare_v2(db_, sql.c_str(), -1, &st, nullptr) != SQLITE_OK) {
      ADD_FAILURE() << sql << ": " << sqlite3_errmsg(db_);
      return out;
    }
    while (sqlite3_step(st) == SQLITE_ROW) {
      if (!out.empty()) out += "\n";
      const unsigned char* p = sqlite3_column_text(st, 0);
      out += p ? reinterpret_cast<const char*>(p) : "NULL";
    }
    sqlite3_finalize(st);
    return out;
  }
  /// The first column of the first row as a double; none for NULL or no row.
  std::optional<double> real(const std::string& sql) {
    sqlite3_stmt* st = nullptr;
    std::optional<double> out;
    if (sqlite3_prepare_v2(db_, sql.c_str(), -1, &st, nullptr) != SQLITE_OK) {
      ADD_FAILURE() << sql << ": " << sqlite3_errmsg(db_);
      return out;
    }
    if (sqlite3_step(st) == SQLITE_ROW && sqlite3_column_type(st, 0) != SQLITE_NULL)
      out = sqlite3_column_double(st, 0);
    sqlite3_finalize(st);
    return out;
  }

 private:
  sqlite3* db_ = nullptr;
};

std::string file_bytes(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
}

TEST(Migration, FreshDatabaseGetsTheCurrentVersionOurApplicationIdAndWal) {
  TempDir dir;
  const std::string path = dir.file("fresh.db");
  {
    SqliteRepository repo(path);
    EXPECT_EQ(repo.schema_version(), schema::kSchemaVersion);
    EXPECT_EQ(schema::kSchemaVersion, static_cast<int>(schema::migrations().size()));
  }
  RawDb raw(path);
  EXPECT_EQ(raw.text("PRAGMA user_version"), std::to_string(schema::kSchemaVersion));
  EXPECT_EQ(raw.text("PRAGMA application_id"), std::to_string(0x494D5543));
  EXPECT_EQ(raw.text("PRAGMA journal_mode"), "wal") << "WAL is persistent in the file";
  EXPECT_EQ(raw.text("SELECT group_concat(name, ',') FROM (SELECT name FROM sqlite_schema WHERE "
                     "type = 'table' AND name NOT LIKE 'sqlite_%' ORDER BY name)"),
            "ains_values,calibrations,crosschecks,outbox,outbox_state,runs,units");
  EXPECT_EQ(raw.text("PRAGMA integrity_check"), "ok");
  EXPECT_EQ(raw.text("PRAGMA foreign_key_check"), "");
}

TEST(Migration, ReopeningIsIdempotentAndKeepsData) {
  TempDir dir;
  const std::string path = dir.file("reopen.db");
  RunId id = 0;
  {
    SqliteRepository repo(path);
    id = repo.create_run(test::new_run("SIM-0001", kT0Migration));
    repo.finish_run(id, test::pass_completion(3, kT0Migration + 1000));
  }
  const std::string schema_before = RawDb(path).text("SELECT sql FROM sqlite_schema ORDER BY name");
  for (int i = 0; i < 3; ++i) {
    SqliteRepository repo(path);
    EXPECT_EQ(repo.schema_version(), schema::kSchemaVersion);
    ASSERT_EQ(repo.history("SIM-0001").size(), 1u);
    EXPECT_EQ(repo.history("SIM-0001")[0].run_id, id);
  }
  EXPECT_EQ(RawDb(path).text("SELECT sql FROM sqlite_schema ORDER BY name"), schema_before);
}

TEST(Migration, NewerSchemaVersionIsRefusedAndTheFileLeftUntouched) {
  TempDir dir;
  const std::string path = dir.file("future.db");
  {
    SqliteRepository repo(path);
    repo.create_run(test::new_run("SIM-0001", kT0Migration));
  }
  RawDb(path).exec("PRAGMA user_version = 99");
  const std::string before = file_bytes(path);
  const std::string msg =
      expect_throw_message<IncompatibleSchema>([&] { SqliteRepository r(path); });
  EXPECT_NE(msg.find(path), std::string::npos) << msg;
  EXPECT_NE(msg.find("99"), std::string::npos) << msg;
  EXPECT_NE(msg.find("newer than this software supports (" +
                     std::to_string(schema::kSchemaVersion) + ")"),
            std::string::npos)
      << msg;
  SqliteOptions ro;
  ro.read_only = true;
  EXPECT_THROW(SqliteRepository r(path, ro), IncompatibleSchema);
  EXPECT_EQ(file_bytes(path), before) << "a refused file is not modified";
  EXPECT_EQ(RawDb(path).text("PRAGMA user_version"), "99");
}

TEST(Migration, ForeignAndNonDatabaseFilesAreRefused) {
  TempDir dir;
  // Tables but no version: somebody else's database.
  const std::string foreign = dir.file("foreign.db");
  RawDb(foreign).exec("CREATE TABLE stuff (x INTEGER); INSERT INTO stuff VALUES (1);");
  const std::string before = file_bytes(foreign);
  std::string msg = expect_throw_message<IncompatibleSchema>([&] { SqliteRepository r(foreign); });
  EXPECT_NE(msg.find("not created by this software"), std::string::npos) << msg;
  EXPECT_EQ(file_bytes(foreign), before);

  // Another application's id.
  const std::string other = dir.file("other.db");
  RawDb(other).exec("PRAGMA application_id = 1234; PRAGMA user_version = " +
                    std::to_string(schema::kSchemaVersion) + ";");
  msg = expect_throw_message<IncompatibleSchema>([&] { SqliteRepository r(other); });
  EXPECT_NE(msg.find("not a calibration-history database"), std::string::npos) << msg;

  // Not an SQLite file at all.
  const std::string text = dir.file("notes.db");
  std::ofstream(text) << "this is a text file, long enough to have what looks like a header......"
                         "..................................................................\n";
  msg = expect_throw_message<Corrupt>([&] { SqliteRepository r(text); });
  EXPECT_NE(msg.find(text), std::string::npos) << msg;

  // An empty SQLite file opened read-only: no schema yet, and read-only cannot create it.
  const std::string empty = dir.file("empty.db");
  RawDb(empty).exec("PRAGMA user_version = 0");
  SqliteOptions ro;
  ro.read_only = true;
  msg = expect_throw_message<IncompatibleSchema>([&] { SqliteRepository r(empty, ro); });
  EXPECT_NE(msg.find("no calibration-history schema"), std::string::npos) << msg;
}

TEST(Migration, LaterMigrationsApplyInOrderAndAFailingOneRollsBackCompletely) {
  TempDir dir;
  const std::string path = dir.file("mig.db");
  { SqliteRepository repo(path); }
  RawDb raw(path);
  const int v = schema::kSchemaVersion;
  const std::string vs = std::to_string(v);

  // Hypothetical versions v+1 and v+2, the second failing halfway: nothing of either may remain.
  std::vector<schema::Migration> broken = schema::migrations();
  broken.push_back({v + 1, "add a column", "ALTER TABLE units ADD COLUMN model TEXT;"});
  broken.push_back(
      {v + 2, "broken", "CREATE TABLE extra (x INTEGER); INSERT INTO no_such_table VALUES (1);"});
  EXPECT_THROW(schema::migrate(raw.get(), path, broken), IoError);
  EXPECT_EQ(raw.text("PRAGMA user_version"), vs);
  EXPECT_EQ(raw.text("SELECT count(*) FROM sqlite_schema WHERE name = 'extra'"), "0");
  EXPECT_EQ(raw.text("SELECT count(*) FROM pragma_table_info('units') WHERE name = 'model'"), "0");

  // The same list without the broken step: version v+1, column present; again is a no-op.
  broken.pop_back();
  EXPECT_EQ(schema::migrate(raw.get(), path, broken), v);
  EXPECT_EQ(raw.text("PRAGMA user_version"), std::to_string(v + 1));
  EXPECT_EQ(raw.text("SELECT count(*) FROM pragma_table_info('units') WHERE name = 'model'"), "1");
  EXPECT_EQ(schema::migrate(raw.get(), path, broken), v + 1);

  // This software now refuses the newer file.
  EXPECT_THROW(SqliteRepository r(path), IncompatibleSchema);

  // Gaps in a migration list are a programming error.
  std::vector<schema::Migration> gap = schema::migrations();
  gap.push_back({v + 3, "gap", "SELECT 1;"});
  EXPECT_THROW(schema::migrate(raw.get(), path, gap), std::logic_error);
}

TEST(Migration, VersionOneDatabaseUpgradesToTheCurrentKeepingItsRunsAndGainsCaptureJson) {
  TempDir dir;
  const std::string path = dir.file("v1.db");
  // A file as the first station release wrote it: only migration 1 applied, one finished run.
  {
    RawDb raw(path);
    const std::vector<schema::Migration> v1(schema::migrations().begin(),
                                            schema::migrations().begin() + 1);
    schema::migrate(raw.get(), path, v1);
    ASSERT_EQ(raw.text("PRAGMA user_version"), "1");
    ASSERT_EQ(raw.text("SELECT count(*) FROM pragma_table_info('runs') WHERE name = "
                       "'capture_json'"),
              "0");
    raw.exec("INSERT INTO units (serial, first_seen_ms) VALUES ('OLD-1', 1714560000000);");
    raw.exec(
        "INSERT INTO runs (unit_id, operator, station, sequence_name, sequence_sha256, "
        "software_version, started_at_ms, ended_at_ms, state, failure_reason) VALUES "
        "(1, 'op', 'st', 'short', '', '0.0.9', 1714560000000, 1714560060000, 'aborted', "
        "'operator abort');");
  }
  // A read-only reader refuses the old file with advice; read-write migrates it.
  SqliteOptions ro;
  ro.read_only = true;
  const std::string msg =
      expect_throw_message<IncompatibleSchema>([&] { SqliteRepository r(path, ro); });
  EXPECT_NE(msg.find("open it read-write once"), std::string::npos) << msg;
  {
    SqliteRepository repo(path);
    EXPECT_EQ(repo.schema_version(), schema::kSchemaVersion);
    const auto runs = repo.history("OLD-1");
    ASSERT_EQ(runs.size(), 1u);
    EXPECT_EQ(runs[0].state, RunState::kAborted);
    EXPECT_EQ(runs[0].failure_reason, "operator abort");
    EXPECT_EQ(runs[0].capture_json, "") << "old runs have no capture summary";
    EXPECT_EQ(runs[0].diagnosis_json, "") << "old runs have no diagnosis";
    EXPECT_EQ(repo.integrity_check(), "ok");
  }
  // The new column refuses text that is not JSON, even written around the repository.
  RawDb raw(path);
  char* err = nullptr;
  EXPECT_NE(sqlite3_exec(raw.get(), "UPDATE runs SET capture_json = 'not json' WHERE id = 1",
                         nullptr, nullptr, &err),
            SQLITE_OK);
  sqlite3_free(err);
}

TEST(Migration, CaptureJsonIsStoredWithTheRunAndMalformedTextIsRefused) {
  TempDir dir;
  const std::string path = dir.file("capture.db");
  SqliteRepository repo(path);
  const RunId id = repo.create_run(test::new_run("SIM-0002", kT0Migration));
  RunCompletion bad = test::pass_completion(5, kT0Migration + 1000);
  bad.capture_json = "[1, 2]";
  const std::string msg = expect_throw_message<InvalidInput>([&] { repo.finish_run(id, bad); });
  EXPECT_NE(msg.find("capture_json must be a JSON object"), std::string::npos) << msg;
  EXPECT_TRUE(repo.show(id).calibrations.empty()) << "a refused finish writes nothing";

  RunCompletion ok = test::pass_completion(5, kT0Migration + 1000);
  ok.capture_json = R"({"frames_received":4000,"samples_filled":3})";
  repo.finish_run(id, ok);
  EXPECT_EQ(repo.show(id).run.capture_json, ok.capture_json);
  EXPECT_EQ(repo.history("SIM-0002").at(0).capture_json, ok.capture_json);
  std::string exported;
  repo.export_rows({}, [&](const ExportRow& row) { exported = row.run.capture_json; });
  EXPECT_EQ(exported, ok.capture_json);
}

TEST(Migration, VersionTwoDatabaseGainsDiagnosisJsonKeepingItsCaptureCounters) {
  TempDir dir;
  const std::string path = dir.file("v2.db");
  {
    RawDb raw(path);
    const std::vector<schema::Migration> v2(schema::migrations().begin(),
                                            schema::migrations().begin() + 2);
    schema::migrate(raw.get(), path, v2);
    ASSERT_EQ(raw.text("PRAGMA user_version"), "2");
    raw.exec("INSERT INTO units (serial, first_seen_ms) VALUES ('OLD-2', 1714560000000);");
    raw.exec(
        "INSERT INTO runs (unit_id, operator, station, sequence_name, sequence_sha256, "
        "software_version, started_at_ms, ended_at_ms, state, failure_reason, capture_json) VALUES "
        "(1, 'op', 'st', 'short', '', '0.1.0', 1714560000000, 1714560060000, 'aborted', "
        "'operator abort', '{\"frames_received\":12}');");
  }
  SqliteRepository repo(path);
  EXPECT_EQ(repo.schema_version(), schema::kSchemaVersion);
  const auto runs = repo.history("OLD-2");
  ASSERT_EQ(runs.size(), 1u);
  EXPECT_EQ(runs[0].capture_json, R"({"frames_received":12})");
  EXPECT_EQ(runs[0].diagnosis_json, "");
  // A finished run can be diagnosed afterwards (stationctl diagnose): only its summary changes.
  const std::string summary = R"({"verdict":"explained","best":{"effect":"accel_quadratic_k2"}})";
  repo.set_diagnosis(runs[0].run_id, summary);
  EXPECT_EQ(repo.history("OLD-2").at(0).diagnosis_json, summary);
  EXPECT_EQ(repo.history("OLD-2").at(0).state, RunState::kAborted);
  EXPECT_EQ(repo.integrity_check(), "ok");
}

TEST(Migration, DiagnosisJsonIsStoredWithTheRunAndOnlyAnObjectIsAccepted) {
  TempDir dir;
  SqliteRepository repo(dir.file("diag.db"));
  const RunId id = repo.create_run(test::new_run("SIM-0003", kT0Migration));
  EXPECT_THROW(repo.set_diagnosis(id, R"({"verdict":"consistent"})"), Conflict)
      << "a live run is diagnosed when it has finished";
  RunCompletion bad = test::pass_completion(5, kT0Migration + 1000);
  bad.diagnosis_json = "\"consistent\"";
  const std::string msg = expect_throw_message<InvalidInput>([&] { repo.finish_run(id, bad); });
  EXPECT_NE(msg.find("diagnosis_json must be a JSON object"), std::string::npos) << msg;
  // A PASS cross-check with a significant gap goes to review, with its reason.
  RunCompletion gap = test::pass_completion(5, kT0Migration + 1000);
  gap.state = RunState::kReview;
  gap.reason = "sim-to-real gap: explained by gyro_g_sensitivity";
  gap.diagnosis_json = R"({"verdict":"explained","best":{"effect":"gyro_g_sensitivity"}})";
  repo.finish_run(id, gap);
  const RunDetails d = repo.show(id);
  EXPECT_EQ(d.run.state, RunState::kReview);
  EXPECT_EQ(d.run.diagnosis_json, gap.diagnosis_json);
  EXPECT_THROW(repo.active_params("SIM-0003"), NotFound) << "a review run is never active";
  EXPECT_THROW(repo.set_diagnosis(id, "[1]"), InvalidInput);
  EXPECT_THROW(repo.set_diagnosis(id + 100, "{}"), NotFound);
}

}  // namespace
// Issue #19 item 2: a database written by the previous release (schema 4,
// tests/data/history-v4.sqlite, made by commit 3ff3a6c's SqliteRepository; tests/data/README.md
// lists its runs). Before v5 every view showed the cross-check's verdict as the run's.
TEST(Migration, VersionFourDatabaseFromThePreviousReleaseGainsTheRunVerdictAndReasons) {
  TempDir dir;
  const std::string path = dir.file("history.sqlite");
  std::filesystem::copy_file(IMUCAL_SOURCE_DIR "/tests/data/history-v4.sqlite", path);
  {
    RawDb raw(path);
    ASSERT_EQ(raw.text("PRAGMA user_version"), "4") << "the fixture is a version-4 database";
  }
  SqliteOptions ro;
  ro.read_only = true;
  const std::string msg =
      expect_throw_message<IncompatibleSchema>([&] { SqliteRepository r(path, ro); });
  EXPECT_NE(msg.find("open it read-write once"), std::string::npos) << msg;

  SqliteRepository repo(path);
  EXPECT_EQ(repo.schema_version(), schema::kSchemaVersion);
  EXPECT_EQ(repo.integrity_check(), "ok");
  struct Expected {
    RunId id;
    RunState state;
    std::optional<RunVerdict> verdict;
    std::optional<Verdict> crosscheck;
    const char* source;  ///< the migrated reason's source, or nullptr for none
  };
  const std::vector<Expected> expected = {
      {1, RunState::kDone, RunVerdict::kPass, Verdict::kPass, nullptr},
      {2, RunState::kReview, RunVerdict::kReview, Verdict::kPass, "gap"},
      {3, RunState::kReview, RunVerdict::kReview, Verdict::kReview, "cross-check"},
      {4, RunState::kFailed, RunVerdict::kFailed, std::nullopt, "error"},
      {5, RunState::kAborted, RunVerdict::kAborted, std::nullopt, "aborted"},
      {6, RunState::kReview, RunVerdict::kReview, Verdict::kPass, "partial archive"},
      {7, RunState::kDone, RunVerdict::kPass, Verdict::kPass, nullptr},
      {8, RunState::kDone, RunVerdict::kPass, Verdict::kPass, nullptr},
      {9, RunState::kReview, RunVerdict::kReview, std::nullopt, "field"},
      {10, RunState::kInterrupted, RunVerdict::kInterrupted, std::nullopt, "interrupted"},
      {11, RunState::kRunning, std::nullopt, std::nullopt, nullptr},
  };
  for (const Expected& e : expected) {
    const RunDetails d = repo.show(e.id);
    EXPECT_EQ(d.run.state, e.state) << "run " << e.id;
    EXPECT_EQ(d.run.verdict, e.verdict) << "run " << e.id;
    EXPECT_EQ(d.run.crosscheck_verdict, e.crosscheck) << "run " << e.id;
    // v9: every run stored before keeps AINS as the set it makes active, with no judgement.
    EXPECT_EQ(d.run.holding_method, Method::kAins) << "run " << e.id;
    EXPECT_EQ(d.run.holding_reason, "") << "run " << e.id;
    if (e.source) {
      ASSERT_EQ(d.run.reasons.size(), 1u) << "run " << e.id;
      EXPECT_EQ(d.run.reasons[0].source, e.source) << "run " << e.id;
      EXPECT_EQ(d.run.reasons[0].text, d.run.failure_reason) << "kept whole, run " << e.id;
    } else {
      EXPECT_TRUE(d.run.reasons.empty()) << "run " << e.id;
    }
  }
  // The data the previous release stored are all there, values unchanged.
  const RunDetails first = repo.show(1);
  ASSERT_EQ(first.calibrations.size(), 2u);
  EXPECT_TRUE(first.calibrations[0].params.to_vector() == test::seeded_params(1, 0).to_vector());
  EXPECT_TRUE(first.calibrations[1].sigma.to_vector() == test::seeded_sigma(1, 1).to_vector());
  EXPECT_EQ(first.run.capture_json, R"({"frames_received":38400,"samples_lost":0})");
  EXPECT_EQ(repo.show(3).crosscheck->failures.size(), 1u);
  EXPECT_EQ(*repo.show(9).run.promoted_at_ms, 1780000000000 + 8 * 3600000LL + 30 * 60000LL);
  EXPECT_EQ(repo.active_params("V4-A").run.run_id, 1) << "the later REVIEW runs never replace it";
  EXPECT_EQ(repo.active_params("V4-C").run.run_id, 9) << "QA's promotion stands";
  EXPECT_EQ(repo.active_params("V4-A").active.method, Method::kAins);
  EXPECT_EQ(repo.active_params("V4-C").active.method, Method::kAins);
  // Field results stored before v5 say what they could not observe, as new ones do.
  for (const RunId field : {8, 9}) {
    for (const CalibrationRecord& c : repo.show(field).calibrations) {
      EXPECT_EQ(c.body_frame, calib::core::BodyFrame::kAccelSymmetric) << "run " << field;
      EXPECT_EQ(c.unobservable.size(), 3u) << "run " << field;
      ASSERT_EQ(c.notes.size(), 2u) << "run " << field;
      EXPECT_NE(c.notes[0].find(field == 9 ? "at sea" : "on land"), std::string::npos)
          << c.notes[0];
    }
  }
  EXPECT_EQ(repo.show(8).crosscheck->not_compared.size(), 3u);
  EXPECT_TRUE(repo.show(1).crosscheck->not_compared.empty());
  EXPECT_EQ(repo.show(1).calibrations[0].body_frame, calib::core::BodyFrame::kHousing);
  // Every view reads the same verdict: export rows as show.
  std::size_t rows = 0;
  repo.export_rows({}, [&](const ExportRow& row) {
    ++rows;
    EXPECT_EQ(row.run.verdict, repo.show(row.run.run_id).run.verdict) << row.run.run_id;
  });
  EXPECT_EQ(rows, 17u) << "6 runs with two methods, 1 with one, 4 without";
  // The verdict must fit the state (v10 triggers): it cannot be written around the code.
  RawDb raw(path);
  char* err = nullptr;
  EXPECT_NE(sqlite3_exec(raw.get(), "UPDATE runs SET verdict = 'PASS' WHERE id = 2", nullptr,
                         nullptr, &err),
            SQLITE_OK);
  sqlite3_free(err);
  EXPECT_EQ(raw.text("SELECT verdict FROM runs WHERE id = 2"), "REVIEW");
  EXPECT_EQ(raw.text("SELECT count(*) FROM runs WHERE verdict = 'PASS'"), "3");
}

// Schema v10 (issue #50): a version-9 database whose ended runs were all "FAILED" — a table that
// could not be reached, an operator's abort, a CAN bus gone, a full disk, a daemon that died, and
// the unit's own data — migrates to verdicts that say whose each end was, by the run's state and
// the reason texts the station writes. The expected verdicts are written out by hand per row.
TEST(Migration, VersionNineRunsAreClassifiedByWhoseTheirEndWas) {
  TempDir dir;
  const std::string path = dir.file("v9.db");
  struct OldRun {
    const char* state;
    const char* reason;
    std::optional<RunVerdict> expected;
  };
  const std::vector<OldRun> old_runs = {
      {"done", "", RunVerdict::kPass},
      {"review", "cross-check REVIEW: accel_bias_mps2[1]: too far", RunVerdict::kReview},
      {"aborted",
       "table: turntable tcp:127.0.0.1:1502: cannot connect after 10 attempt(s): Connection "
       "refused",
       RunVerdict::kStationFault},
      {"aborted", "table: turntable tcp:127.0.0.1:1502 during a rest: e-stop open",
       RunVerdict::kStationFault},
      {"aborted", "unit loose in fixture", RunVerdict::kAborted},
      {"aborted", "unit loose in fixture (then: table: turntable: aborted)", RunVerdict::kAborted},
      {"failed", "capture: CAN channel error: unixcan:/run/imu.sock: peer closed the connection",
       RunVerdict::kStationFault},
      {"failed",
       "capture: CAN controller can0 went bus-off at row 12 (t = 0.12 s) (after 40 error frames)",
       RunVerdict::kStationFault},
      {"failed", "capture: unixcan:/run/imu.sock: cannot connect to /run/imu.sock: refused",
       RunVerdict::kStationFault},
      {"failed", "capture: run archive write failed: No space left on device",
       RunVerdict::kStationFault},
      {"failed", "archive: No space left on device", RunVerdict::kStationFault},
      {"failed", "import: cannot store the archive: No space left on device",
       RunVerdict::kStationFault},
      {"failed", "capture: IMU stream timeout: no sample for 2000 ms after row 5 (t = 0.05 s)",
       RunVerdict::kFailed},
      {"failed", "capture: IMU reports gyro x failure at row 100 (t = 1.00 s)",
       RunVerdict::kFailed},
      {"failed", "calibration failed: data check: accelerometer axis y stuck at 0.000 m/s²",
       RunVerdict::kFailed},
      {"interrupted", "the station daemon stopped while the run was running (found at start-up)",
       RunVerdict::kInterrupted},
      {"running", "", std::nullopt},
  };
  {
    RawDb raw(path);
    const std::vector<schema::Migration> v9(schema::migrations().begin(),
                                            schema::migrations().begin() + 9);
    schema::migrate(raw.get(), path, v9);
    ASSERT_EQ(raw.text("PRAGMA user_version"), "9");
    raw.exec("INSERT INTO units (serial, first_seen_ms) VALUES ('V9-1', 1714560000000);");
    for (std::size_t i = 0; i < old_runs.size(); ++i) {
      const bool live = std::string(old_runs[i].state) == "running";
      raw.exec(
          "INSERT INTO runs (unit_id, operator, station, sequence_name, sequence_sha256, "
          "software_version, started_at_ms, ended_at_ms, state, failure_reason, uuid) VALUES "
          "(1, 'op', 'st', 'short', '', '0.9', " +
          std::to_string(kT0Migration + static_cast<TimestampMs>(i)) + ", " +
          (live ? std::string("NULL") : std::to_string(kT0Migration + 1000)) + ", '" +
          old_runs[i].state + "', '" + old_runs[i].reason + "', lower(hex(randomblob(16))));");
    }
    ASSERT_EQ(raw.text("SELECT count(*) FROM runs WHERE verdict = 'FAILED'"), "14")
        << "version 9: every ended run that is not done or review is FAILED";
  }
  SqliteRepository repo(path);
  EXPECT_EQ(repo.schema_version(), schema::kSchemaVersion);
  EXPECT_EQ(repo.integrity_check(), "ok");
  for (std::size_t i = 0; i < old_runs.size(); ++i) {
    const RunRecord r = repo.show(static_cast<RunId>(i + 1)).run;
    EXPECT_EQ(r.verdict, old_runs[i].expected) << old_runs[i].state << ": " << old_runs[i].reason;
    EXPECT_EQ(r.failure_reason, old_runs[i].reason) << "the reason is kept";
  }
  // The station's copy of each ended run changed: its revision moved, so a fleet store takes it.
  RawDb raw(path);
  EXPECT_EQ(raw.text("SELECT count(*) FROM runs WHERE revision > 0"), "16");
  // The stored verdict must fit the state, also around the code.
  for (const char* bad : {"UPDATE runs SET verdict = 'FAILED' WHERE id = 1",
                          "UPDATE runs SET verdict = 'ABORTED' WHERE id = 7",
                          "UPDATE runs SET verdict = NULL WHERE id = 3",
                          "UPDATE runs SET verdict = 'PASS' WHERE id = 17"}) {
    char* err = nullptr;
    EXPECT_NE(sqlite3_exec(raw.get(), bad, nullptr, nullptr, &err), SQLITE_OK) << bad;
    sqlite3_free(err);
  }
  EXPECT_EQ(raw.text("SELECT verdict FROM runs WHERE id IN (1, 3, 7, 17) ORDER BY id"),
            "PASS\nSTATION-FAULT\nSTATION-FAULT\nNULL");
}

// Schema v8 (issue #24, the fleet pages): ains_values holds every stored AINS result's values as
// numbers — filled by the migration for the results already stored (here the previous releases'
// file, migrated 4 -> 8), kept by triggers afterwards — and NULL where the result does not
// determine the parameter. Compared with the repository's own reading of the parameter-set JSON.
TEST(Migration, VersionEightHoldsEveryAinsResultAsNumbersAndKeepsThemWithTheirJson) {
  TempDir dir;
  const std::string path = dir.file("history.sqlite");
  std::filesystem::copy_file(IMUCAL_SOURCE_DIR "/tests/data/history-v4.sqlite", path);
  SqliteRepository repo(path);
  ASSERT_EQ(repo.schema_version(), schema::kSchemaVersion);
  RawDb raw(path);
  auto value_of = [&](RunId id, int i) {
    char sql[96];
    std::snprintf(sql, sizeof sql, "SELECT p%02d FROM ains_values WHERE run_id = %lld", i,
                  static_cast<long long>(id));
    return raw.real(sql);
  };
  int results = 0, undetermined = 0;
  for (RunId id = 1; id <= 11; ++id) {
    for (const CalibrationRecord& c : repo.show(id).calibrations) {
      if (c.method != Method::kAins) continue;
      ++results;
      const calib::core::ParamVector x = c.params.to_vector();
      for (int i = 0; i < calib::core::ParamSet::kSize; ++i) {
        const std::string& name = calib::core::param_info(i).name;
        SCOPED_TRACE("run " + std::to_string(id) + " " + name);
        const std::optional<double> got = value_of(id, i);
        if (std::find(c.unobservable.begin(), c.unobservable.end(), name) != c.unobservable.end()) {
          EXPECT_FALSE(got) << "a placeholder value was kept";
          ++undetermined;
        } else {
          ASSERT_TRUE(got);
          EXPECT_EQ(*got, x(i));
        }
      }
    }
  }
  EXPECT_GE(results, 5) << "the fixture holds AINS results";
  EXPECT_GT(undetermined, 0) << "the fixture holds field results that leave terms undetermined";
  EXPECT_EQ(raw.text("SELECT count(*) FROM ains_values"), std::to_string(results));

  // The triggers: a result changed or removed by hand carries its numbers along.
  raw.exec(
      "UPDATE calibrations SET params_json = json_set(params_json, '$.gyro_bias_radps[2]', 1.5) "
      "WHERE run_id = 1 AND method = 'ains'");
  EXPECT_EQ(value_of(1, 14), 1.5);
  raw.exec("DELETE FROM calibrations WHERE run_id = 1 AND method = 'ains'");
  EXPECT_EQ(raw.text("SELECT count(*) FROM ains_values WHERE run_id = 1"), "0");
  EXPECT_EQ(raw.text("SELECT count(*) FROM ains_values"), std::to_string(results - 1));
  EXPECT_EQ(repo.integrity_check(), "ok");
}

}  // namespace imucal::db
