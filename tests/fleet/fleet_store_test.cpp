// The fleet store on a real PostgreSQL server (a throw-away cluster, tests/support/pg_cluster.hpp):
// a station's runs written by the writer read back field by field equal through the fleet
// repository; resends are no-ops and an older revision never replaces a newer one; the reader role
// cannot write; filters are bound values; the password never shows; bad targets are clear errors.
#include <gtest/gtest.h>

#include <map>
#include <nlohmann/json.hpp>

#include "db/fleet/fleet_repository.hpp"
#include "db/fleet/fleet_schema.hpp"
#include "db/fleet/fleet_writer.hpp"
#include "db/fleet/pg_fleet_stats.hpp"
#include "db/history/sqlite_repository.hpp"
#include "tests/db/history_fixtures.hpp"
#include "tests/support/fleet_compare.hpp"
#include "tests/support/pg_cluster.hpp"

namespace imucal::db::fleet {
using namespace imucal::db::history;
namespace {

using test_support::PgCluster;
constexpr TimestampMs kT0 = 1714560000000;

FleetTarget writer(const PgCluster& pg) {
  return parse_fleet_target(pg.url("fleet_writer"), PgCluster::kWriterPassword);
}
FleetTarget reader(const PgCluster& pg) {
  return parse_fleet_target(pg.url("fleet_reader"), PgCluster::kReaderPassword);
}

/// A station history with every kind of run: PASS, REVIEW, failed, live, a promoted land run, a
/// reprocess, a table run of two slots, a diagnosis.
void fill_station(SqliteRepository& repo, const std::string& station, long seed) {
  auto run = [&](const std::string& serial, TimestampMs t) {
    NewRun n = test::new_run(serial, t);
    n.station = station;
    return n;
  };
  const RunId pass = repo.create_run(run("SN-A", kT0 + seed));
  repo.finish_run(pass, test::pass_completion(seed, kT0 + seed + 100));
  repo.set_diagnosis(pass, R"({"verdict":"consistent","gap":1.5})");
  const RunId review = repo.create_run(run("SN-A", kT0 + seed + 200));
  repo.finish_run(review, test::review_completion(seed + 1, kT0 + seed + 300));
  NewRun again = run("SN-A", kT0 + seed + 400);
  again.reprocessed_from = review;
  const RunId re = repo.create_run(again);
  repo.update_run_state(re, RunState::kFailed, "archive unreadable: x.csv line 3");
  NewRun a = run("SN-B", kT0 + seed + 500);
  a.slot = "A";
  const RunId first = repo.create_run(a);
  NewRun b = run("SN-C", kT0 + seed + 500);
  b.slot = "B";
  b.table_run_id = first;
  const RunId second = repo.create_run(b);
  repo.finish_run(first, test::pass_completion(seed + 2, kT0 + seed + 600));
  repo.update_run_state(second, RunState::kRunning);
}

std::map<RunId, std::string> uuids(const std::vector<RunDetails>& runs) {
  std::map<RunId, std::string> m;
  for (const RunDetails& d : runs) m[d.run.run_id] = d.run.uuid;
  return m;
}

std::vector<RunDetails> all_runs(const SqliteRepository& repo) {
  std::vector<RunId> ids;
  for (const RunRecord& r : repo.recent_runs(0)) ids.push_back(r.run_id);
  return repo.details_of(ids);
}

TEST(FleetStore, RunsReadBackFieldByFieldAndResendsChangeNothing) {
  PgCluster pg;
  test::TempDir dir;
  SqliteRepository s1(dir.file("s1.db")), s2(dir.file("s2.db"));
  fill_station(s1, "ST-1", 1);
  fill_station(s2, "ST-2", 2);
  PgConnection w(writer(pg));
  EXPECT_EQ(migrate_fleet(w), 0);
  EXPECT_EQ(migrate_fleet(w), kFleetSchemaVersion) << "a second migration finds it current";
  const auto runs1 = all_runs(s1), runs2 = all_runs(s2);
  EXPECT_EQ(upsert_runs(w, "ST-1", runs1).written, runs1.size());
  EXPECT_EQ(upsert_runs(w, "ST-2", runs2).written, runs2.size());
  const UpsertCount again = upsert_runs(w, "ST-1", runs1);
  EXPECT_EQ(again.written, 0u);
  EXPECT_EQ(again.unchanged, runs1.size());

  FleetRepository fleet(reader(pg));
  EXPECT_EQ(fleet.total_run_count(), runs1.size() + runs2.size());
  std::vector<RunId> fleet_ids;
  for (const RunRecord& r : fleet.recent_runs(0)) fleet_ids.push_back(r.run_id);
  std::vector<RunDetails> from_fleet;
  for (RunId id : fleet_ids) from_fleet.push_back(fleet.show(id));
  const auto fleet_uuids = uuids(from_fleet);
  std::map<std::string, nlohmann::json> stored;
  for (const RunDetails& d : from_fleet)
    stored[d.run.uuid] = test_support::comparable_run(d, fleet_uuids);
  for (const auto* runs : {&runs1, &runs2}) {
    const auto local = uuids(*runs);
    for (const RunDetails& d : *runs) {
      ASSERT_TRUE(stored.count(d.run.uuid)) << d.run.uuid;
      EXPECT_EQ(stored[d.run.uuid], test_support::comparable_run(d, local));
    }
  }
  // history across stations, newest first, and the active set of the fleet.
  const auto hist = fleet.history("SN-A");
  ASSERT_EQ(hist.size(), 6u);
  EXPECT_EQ(hist.front().station, "ST-2");
  EXPECT_EQ(fleet.run_count("SN-A"), 6u);
  // One station's share, counted where it is kept (what `history --station` shows N of).
  EXPECT_EQ(fleet.station_run_count("ST-1", std::nullopt), runs1.size());
  EXPECT_EQ(fleet.station_run_count("ST-1", std::string("SN-A")), 3u);
  EXPECT_EQ(fleet.station_run_count("ST-9", std::nullopt), 0u);
  EXPECT_EQ(s1.station_run_count("ST-1", std::string("SN-A")), 3u);
  EXPECT_EQ(fleet.active_params("SN-A").run.station, "ST-2");
  EXPECT_EQ(fleet.runs_in_state({RunState::kRunning, RunState::kPreparing}).size(), 2u)
      << "one live run per station";
  EXPECT_THROW(fleet.history("SN-NONE"), NotFound);
  EXPECT_THROW(fleet.show(999999), NotFound);
  std::size_t rows = 0;
  ExportFilter only1;
  only1.station = "ST-1";
  fleet.export_rows(only1, [&](const ExportRow& r) {
    EXPECT_EQ(r.run.station, "ST-1");
    ++rows;
  });
  std::size_t sqlite_rows = 0;
  s1.export_rows({}, [&](const ExportRow&) { ++sqlite_rows; });
  EXPECT_EQ(rows, sqlite_rows);
  const auto stations = fleet.stations();
  ASSERT_EQ(stations.size(), 2u);
  EXPECT_EQ(stations[0].second, runs1.size());
}

// Issue #48 item 7: a land run whose rests the legacy fit holds and AINS does not reaches the
// fleet store with its holding method and why, and the fleet's active set of the unit is that
// run's legacy set, as the station's is.
TEST(FleetStore, ALandRunThatRestsOnLegacyIsActiveOnLegacyInTheFleetToo) {
  PgCluster pg;
  test::TempDir dir;
  SqliteRepository station(dir.file("s.db"));
  NewRun n = test::new_run("SN-L", kT0);
  n.setting = calib::core::Setting::kLand;
  const RunId land = station.create_run(n);
  RunCompletion c = test::pass_completion(7, kT0 + 100);
  c.calibrations = {test::seeded_calibration(7, Method::kAins, false),
                    test::seeded_calibration(7, Method::kLegacy, false)};
  c.crosscheck = CrosscheckRecord{Verdict::kReview, 4.0, {{"accel_bias_mps2[2]", "apart"}}, {}};
  c.holding_method = Method::kLegacy;
  c.holding_reason = "AINS leaves 0.20 mg over the 40 rests against legacy's 0.11 mg";
  station.finish_run(land, c);
  station.promote(land, "qa", "field calibration", kT0 + 200);
  ASSERT_EQ(station.active_params("SN-L").active.method, Method::kLegacy);

  PgConnection w(writer(pg));
  migrate_fleet(w);
  const auto runs = all_runs(station);
  EXPECT_EQ(upsert_runs(w, "ST-L", runs).written, 1u);
  FleetRepository fleet(reader(pg));
  const ActiveCalibration a = fleet.active_params("SN-L");
  EXPECT_EQ(a.run.holding_method, Method::kLegacy);
  EXPECT_EQ(a.run.holding_reason, c.holding_reason);
  EXPECT_EQ(a.active.method, Method::kLegacy);
  EXPECT_EQ(a.active.params.to_vector(),
            test::seeded_calibration(7, Method::kLegacy, false).params.to_vector());
  const RunDetails stored = fleet.show(a.run.run_id);
  EXPECT_EQ(test_support::comparable_run(stored, uuids({stored})),
            test_support::comparable_run(runs.front(), uuids(runs)));
}

TEST(FleetStore, AnOlderRevisionNeverReplacesANewerOne) {
  PgCluster pg;
  test::TempDir dir;
  SqliteRepository s(dir.file("s.db"));
  const RunId id = s.create_run(test::new_run("SN-1", kT0));
  const std::vector<RunDetails> live = s.details_of({id});
  s.finish_run(id, test::pass_completion(1, kT0 + 100));
  const std::vector<RunDetails> done = s.details_of({id});
  PgConnection w(writer(pg));
  migrate_fleet(w);
  EXPECT_EQ(upsert_runs(w, "ST", done).written, 1u);
  EXPECT_EQ(upsert_runs(w, "ST", live).unchanged, 1u) << "a stale resync copy arrives late";
  FleetRepository fleet(reader(pg));
  const RunDetails back = fleet.show(fleet.recent_runs(1).at(0).run_id);
  EXPECT_EQ(back.run.state, RunState::kDone);
  EXPECT_EQ(back.calibrations.size(), 2u);
}

/// The store's runs read back, keyed by run UUID (references as the other runs' UUIDs).
std::map<std::string, nlohmann::json> stored_runs(const FleetRepository& fleet) {
  std::vector<RunDetails> from_fleet;
  for (const RunRecord& r : fleet.recent_runs(0)) from_fleet.push_back(fleet.show(r.run_id));
  const auto fleet_uuids = uuids(from_fleet);
  std::map<std::string, nlohmann::json> stored;
  for (const RunDetails& d : from_fleet)
    stored[d.run.uuid] = test_support::comparable_run(d, fleet_uuids);
  return stored;
}

// A station whose disk was replaced starts a new database: its local ids restart at 1 under new
// run UUIDs. The store refuses them (another run under the same local id) and names the way out.
// Resync then sets the old runs apart under `<id>.previous-<time>`, every one kept as it was (its
// references to its reprocess origin and its table run still resolving), and stores the new
// database's runs beside them. Nothing is deleted: the store is the only copy of the old disk's
// quality records. A run the store receives after the mark is never set apart.
TEST(FleetStore, AReplacedStationDatabaseIsRefusedAndResyncKeepsTheOldRunsApart) {
  PgCluster pg;
  test::TempDir dir;
  SqliteRepository old_db(dir.file("old.db")), new_db(dir.file("new.db"));
  fill_station(old_db, "ST-1", 1);
  PgConnection w(writer(pg));
  migrate_fleet(w);
  const auto old_runs = all_runs(old_db);
  ASSERT_EQ(upsert_runs(w, "ST-1", old_runs).written, old_runs.size());
  FleetRepository fleet(reader(pg));
  const auto before = stored_runs(fleet);

  NewRun fresh = test::new_run("SN-NEW", kT0 + 100000);
  fresh.station = "ST-1";
  const RunId first = new_db.create_run(fresh);
  new_db.finish_run(first, test::pass_completion(7, kT0 + 100100));
  const auto new_runs = all_runs(new_db);
  ASSERT_EQ(new_runs.front().run.run_id, old_runs.front().run.run_id) << "ids restart";
  try {
    upsert_runs(w, "ST-1", new_runs);
    FAIL() << "a replaced database's run was stored under an old run's local id";
  } catch (const Conflict& e) {
    EXPECT_NE(std::string(e.what()).find("fleet resync"), std::string::npos) << e.what();
  }

  const ResyncMark mark = begin_resync(w, "ST-1");
  EXPECT_EQ(mark.apart_id.rfind("ST-1.previous-", 0), 0u) << mark.apart_id;
  // The longest station id leaves room for the suffix: the apart id is still a valid one.
  const std::string longest(64, 's');
  const std::string long_apart = begin_resync(w, longest).apart_id;
  EXPECT_EQ(long_apart.size(), 64u) << long_apart;
  EXPECT_NO_THROW(validate_station_id(long_apart));
  EXPECT_NE(long_apart.find(".previous-"), std::string::npos) << long_apart;
  std::vector<std::string> keep;
  for (const RunDetails& d : new_runs) keep.push_back(d.run.uuid);
  EXPECT_EQ(set_apart_runs_not_in(w, "ST-1", keep, mark), old_runs.size());
  EXPECT_EQ(upsert_runs(w, "ST-1", new_runs).written, new_runs.size());
  EXPECT_EQ(fleet.total_run_count(), old_runs.size() + new_runs.size()) << "nothing deleted";
  const auto after = stored_runs(fleet);
  for (const auto& [uuid, run] : before) {
    ASSERT_TRUE(after.count(uuid)) << uuid;
    EXPECT_EQ(after.at(uuid), run) << "an old run changed when set apart";
  }
  std::map<std::string, std::size_t> per_station;
  for (const auto& [id, count] : fleet.stations()) per_station[id] = count;
  EXPECT_EQ(per_station["ST-1"], new_runs.size());
  EXPECT_EQ(per_station[mark.apart_id], old_runs.size());
  EXPECT_EQ(fleet.history("SN-A").size(), 3u) << "the old unit's history stays queryable";

  // A run of this database that the sender delivers after the mark: not set apart, even though
  // the keep list (read before it) does not name it.
  NewRun later = test::new_run("SN-NEW", kT0 + 200000);
  later.station = "ST-1";
  const RunId late = new_db.create_run(later);
  upsert_runs(w, "ST-1", new_db.details_of({late}));
  EXPECT_EQ(set_apart_runs_not_in(w, "ST-1", keep, mark), 0u);
  EXPECT_EQ(fleet.stations().size(), 2u);
}

// Issue #50: a store of version 3, whose verdict was generated from the state (every ended run
// that was not done or review FAILED), migrates to version 4 classifying the runs it holds by the
// same rule as the station's history (db/history/schema.cpp, migration 10): the expected verdicts
// are written out by hand per run. The store's counts then keep a station's faults apart from its
// units' outcomes, as the SQLite backend does (tests/fleet/stationweb_fleet_test.cpp).
TEST(FleetStore, AVersionThreeStoreClassifiesItsRunsByWhoseTheirEndWas) {
  PgCluster pg;
  test::TempDir dir;
  SqliteRepository repo(dir.file("station.db"));
  struct Ended {
    RunState state;
    const char* reason;
    RunVerdict expected;
  };
  const std::vector<Ended> ended = {
      {RunState::kAborted,
       "table: turntable tcp:127.0.0.1:1502: cannot connect after 10 attempt(s)",
       RunVerdict::kStationFault},
      {RunState::kAborted, "unit loose in fixture", RunVerdict::kAborted},
      {RunState::kFailed,
       "capture: CAN channel error: unixcan:/run/imu: peer closed the connection",
       RunVerdict::kStationFault},
      {RunState::kFailed, "archive: No space left on device", RunVerdict::kStationFault},
      {RunState::kFailed, "calibration failed: data check: accelerometer axis y stuck",
       RunVerdict::kFailed},
      {RunState::kInterrupted, "the station daemon stopped while the run was running",
       RunVerdict::kInterrupted},
  };
  const RunId pass = repo.create_run(test::new_run("SN-A", kT0));
  repo.finish_run(pass, test::pass_completion(1, kT0 + 100));
  for (std::size_t i = 0; i < ended.size(); ++i) {
    const RunId id = repo.create_run(test::new_run("SN-A", kT0 + 1000 * (1 + i)));
    repo.update_run_state(id, ended[i].state, ended[i].reason);
  }
  PgConnection w(writer(pg));
  migrate_fleet(w);
  upsert_runs(w, "st-1", all_runs(repo));
  // Back to version 3 as the previous release left it: the verdict generated from the state.
  pg.admin(
      "ALTER TABLE runs DROP CONSTRAINT runs_verdict_fits_state; DROP INDEX runs_by_time_counts; "
      "ALTER TABLE runs DROP COLUMN verdict; ALTER TABLE runs ADD COLUMN verdict text GENERATED "
      "ALWAYS AS (CASE state WHEN 'done' THEN 'PASS' WHEN 'review' THEN 'REVIEW' WHEN 'failed' "
      "THEN 'FAILED' WHEN 'aborted' THEN 'FAILED' WHEN 'interrupted' THEN 'FAILED' END) STORED; "
      "CREATE INDEX runs_by_time_counts ON runs (started_at_ms) INCLUDE (station_id, verdict); "
      "DELETE FROM fleet_schema_version WHERE version = 4;",
      "fleet");
  EXPECT_EQ(pg.admin("SELECT count(*) FROM runs WHERE verdict = 'FAILED'", "fleet"), "6\n")
      << "version 3: all six ended runs FAILED";
  EXPECT_THROW(FleetRepository{reader(pg)}, IncompatibleSchema) << "a reader waits for a writer";
  EXPECT_EQ(migrate_fleet(w), 3);
  const FleetRepository fleet(reader(pg));
  std::map<std::string, std::optional<RunVerdict>> got, expected;
  for (const RunRecord& r : fleet.history("SN-A")) got[r.failure_reason] = r.verdict;
  expected[""] = RunVerdict::kPass;
  for (const Ended& e : ended) expected[e.reason] = e.expected;
  EXPECT_EQ(got, expected);
  const auto counts = PgFleetStats(reader(pg)).verdict_counts_per_station({});
  ASSERT_EQ(counts.size(), 1u);
  EXPECT_EQ(counts[0].pass, 1);
  EXPECT_EQ(counts[0].failed, 1) << "the unit's own failure alone";
  EXPECT_EQ(counts[0].station_fault, 3);
  EXPECT_EQ(counts[0].aborted, 1);
  EXPECT_EQ(counts[0].interrupted, 1);
  EXPECT_EQ(counts[0].unit_outcomes(), 2);
  // The stored verdict must fit the state in the store too.
  std::string refused;
  try {
    pg.admin("UPDATE runs SET verdict = 'PASS' WHERE state = 'aborted'", "fleet");
  } catch (const std::runtime_error& e) {
    refused = e.what();
  }
  EXPECT_NE(refused.find("runs_verdict_fits_state"), std::string::npos) << refused;
}

TEST(FleetStore, TheReaderRoleCannotWriteAndFiltersAreBoundValues) {
  PgCluster pg;
  test::TempDir dir;
  SqliteRepository s(dir.file("s.db"));
  fill_station(s, "ST-1", 1);
  PgConnection w(writer(pg));
  migrate_fleet(w);
  upsert_runs(w, "ST-1", all_runs(s));
  PgConnection r(reader(pg));
  EXPECT_THROW(r.exec_plain("DELETE FROM runs", "try"), ReadOnly);
  EXPECT_THROW(r.exec_plain("UPDATE runs SET serial = 'X'", "try"), ReadOnly);
  EXPECT_THROW(r.exec_plain("CREATE TABLE t (x int)", "try"), ReadOnly);
  EXPECT_THROW(upsert_runs(r, "ST-1", all_runs(s)), ReadOnly);
  FleetRepository fleet(reader(pg));
  EXPECT_THROW(fleet.create_run(test::new_run("SN-1", kT0)), ReadOnly);

  const std::string evil = "x'; DROP TABLE runs; --";
  ExportFilter f;
  f.station = evil;
  std::size_t rows = 0;
  fleet.export_rows(f, [&](const ExportRow&) { ++rows; });
  EXPECT_EQ(rows, 0u);
  EXPECT_THROW(fleet.history(evil), InvalidInput) << "a serial is validated before any SQL";
  EXPECT_THROW(upsert_runs(w, evil, all_runs(s)), InvalidInput);
  EXPECT_EQ(fleet.total_run_count(), all_runs(s).size()) << "nothing dropped";
}

// A site's own connection parameters in the URL (?application_name=…, ?connect_timeout=…) win over
// the connection's defaults; without them the defaults hold. Before, the defaults were given after
// the URL and libpq let them override it.
TEST(FleetStore, TheUrlsOwnParametersWinOverTheConnectionsDefaults) {
  PgCluster pg;
  auto setting = [](PgConnection& c, const std::string& name) {
    return c.exec("SELECT current_setting($1)", {name}, "setting").text(0, 0);
  };
  PgConnection plain(writer(pg));
  EXPECT_EQ(setting(plain, "application_name"), "imucal");
  PgConnection named(parse_fleet_target(pg.url("fleet_writer") + "?application_name=qa-line-3",
                                        PgCluster::kWriterPassword));
  EXPECT_EQ(setting(named, "application_name"), "qa-line-3");
}

TEST(FleetStore, BadTargetsAreClearErrorsThatNeverShowThePassword) {
  PgCluster pg;
  EXPECT_THROW(parse_fleet_target("postgresql://u@h:notaport/db"), InvalidInput);
  EXPECT_THROW(parse_fleet_target("mysql://x"), InvalidInput);
  EXPECT_THROW(parse_fleet_target(""), InvalidInput);
  const FleetTarget in_url = parse_fleet_target(
      "postgresql://fleet_writer:S3cretInUrl@127.0.0.1:" + std::to_string(pg.port()) + "/fleet");
  EXPECT_EQ(in_url.redacted().find("S3cretInUrl"), std::string::npos);
  EXPECT_NE(in_url.redacted().find("***"), std::string::npos);

  auto message_of = [](const FleetTarget& t) -> std::string {
    try {
      PgConnection c(t);
      FleetRepository repo(t);
    } catch (const DbError& e) {
      return e.what();
    }
    return "";
  };
  const std::string wrong_password = "Wr0ngPassw0rd";
  const std::string m1 = message_of(parse_fleet_target(pg.url("fleet_writer"), wrong_password));
  EXPECT_NE(m1.find("password authentication failed"), std::string::npos) << m1;
  EXPECT_EQ(m1.find(wrong_password), std::string::npos) << m1;
  const std::string m2 = message_of(parse_fleet_target(
      "postgresql://u@127.0.0.1:" + std::to_string(test_support::free_tcp_port()) + "/fleet"));
  EXPECT_NE(m2.find("cannot connect"), std::string::npos) << m2;
  // Expired credentials.
  pg.admin("ALTER ROLE fleet_reader VALID UNTIL '2001-01-01'");
  const std::string m3 = message_of(reader(pg));
  EXPECT_NE(m3.find("cannot connect"), std::string::npos) << m3;
  EXPECT_EQ(m3.find(PgCluster::kReaderPassword), std::string::npos) << m3;
  pg.admin("ALTER ROLE fleet_reader VALID UNTIL 'infinity'");
  // No schema yet, then a newer schema than this software's.
  const std::string m4 = message_of(reader(pg));
  EXPECT_NE(m4.find("no fleet schema"), std::string::npos) << m4;
  PgConnection w(writer(pg));
  migrate_fleet(w);
  pg.admin("INSERT INTO fleet_schema_version (version, description) VALUES (99, 'future')",
           "fleet");
  const std::string m5 = message_of(reader(pg));
  EXPECT_NE(m5.find("schema version 99"), std::string::npos) << m5;
  EXPECT_THROW(migrate_fleet(w), IncompatibleSchema);
}

}  // namespace
}  // namespace imucal::db::fleet
