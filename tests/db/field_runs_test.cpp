// Field runs in the calibration history (issue #9 item 6, schema v4): the setting of every run,
// the legacy method's results, the done rules per setting, QA's explicit promotion, and the rule
// that the active parameters stay the latest factory PASS unless a field run is promoted after it.
#include <gtest/gtest.h>
#include <sqlite3.h>

#include <nlohmann/json.hpp>

#include "db/history/export.hpp"
#include "db/history/schema.hpp"
#include "db/history/sqlite_repository.hpp"
#include "tests/db/history_fixtures.hpp"

namespace imucal::db {
using namespace imucal::db::history;
namespace {

using test::expect_throw_message;
using test::TempDir;

constexpr TimestampMs kT0FieldRuns = 1714560000000;

NewRun field_run(const std::string& serial, TimestampMs t, calib::core::Setting s) {
  NewRun r = test::new_run(serial, t);
  r.setting = s;
  r.origin = "imported from /media/usb/" + serial;
  return r;
}

/// A land run's completion: AINS + legacy and a PASS cross-check.
RunCompletion land_pass(long seed, TimestampMs end) {
  RunCompletion c = test::pass_completion(seed, end);
  c.calibrations = {test::seeded_calibration(seed, Method::kAins, false),
                    test::seeded_calibration(seed, Method::kLegacy, false)};
  return c;
}

/// A sea run: AINS alone, so review with the reason (no cross-check exists).
RunCompletion sea_alone(long seed, TimestampMs end) {
  RunCompletion c;
  c.state = RunState::kReview;
  c.ended_at_ms = end;
  c.reason = "sea: AINS alone, no independent method";
  c.calibrations = {test::seeded_calibration(seed, Method::kAins, false)};
  return c;
}

TEST(FieldRuns, SettingOriginAndLegacyAreStoredAndRead) {
  TempDir dir;
  SqliteRepository repo(dir.file("h.db"));
  const RunId land = repo.create_run(field_run("FOG-1", kT0FieldRuns, calib::core::Setting::kLand));
  repo.finish_run(land, land_pass(1, kT0FieldRuns + 1000));
  const RunDetails d = repo.show(land);
  EXPECT_EQ(d.run.setting, calib::core::Setting::kLand);
  EXPECT_EQ(d.run.origin, "imported from /media/usb/FOG-1");
  ASSERT_EQ(d.calibrations.size(), 2u);
  EXPECT_EQ(d.calibrations[0].method, Method::kAins);
  EXPECT_EQ(d.calibrations[1].method, Method::kLegacy);
  EXPECT_EQ(d.calibrations[1].params.to_vector(),
            test::seeded_calibration(1, Method::kLegacy, false).params.to_vector());
  const RunId fac = repo.create_run(test::new_run("FOG-1", kT0FieldRuns + 5000));
  EXPECT_EQ(repo.show(fac).run.setting, calib::core::Setting::kFactory);
  EXPECT_EQ(repo.integrity_check(), "ok");
}

TEST(FieldRuns, DoneNeedsTheSettingsSecondMethodAndASeaRunIsNeverDone) {
  TempDir dir;
  SqliteRepository repo(dir.file("h.db"));
  // Land with AINS + NLSQ (the factory's pair) is not done: the land pair is AINS + legacy.
  const RunId land = repo.create_run(field_run("FOG-2", kT0FieldRuns, calib::core::Setting::kLand));
  const std::string m1 = expect_throw_message<Conflict>(
      [&] { repo.finish_run(land, test::pass_completion(2, kT0FieldRuns + 1)); });
  EXPECT_NE(m1.find("legacy calibration"), std::string::npos) << m1;
  // A sea run has AINS alone: done is refused, review with the reason is fine.
  const RunId sea =
      repo.create_run(field_run("FOG-2", kT0FieldRuns + 10, calib::core::Setting::kSea));
  RunCompletion done = sea_alone(3, kT0FieldRuns + 20);
  done.state = RunState::kDone;
  const std::string m2 = expect_throw_message<Conflict>([&] { repo.finish_run(sea, done); });
  EXPECT_NE(m2.find("a second method"), std::string::npos) << m2;
  repo.finish_run(sea, sea_alone(3, kT0FieldRuns + 20));
  EXPECT_EQ(repo.show(sea).run.state, RunState::kReview);
}

TEST(FieldRuns, ActiveStaysTheFactoryPassUntilQaPromotesAFieldRun) {
  TempDir dir;
  SqliteRepository repo(dir.file("h.db"));
  const RunId fac1 = repo.create_run(test::new_run("FOG-3", kT0FieldRuns));
  repo.finish_run(fac1, test::pass_completion(10, kT0FieldRuns + 1000));
  // A later land PASS does not replace it on its own.
  const RunId land =
      repo.create_run(field_run("FOG-3", kT0FieldRuns + 2000, calib::core::Setting::kLand));
  repo.finish_run(land, land_pass(11, kT0FieldRuns + 3000));
  EXPECT_EQ(repo.active_params("FOG-3").run.run_id, fac1);
  // QA promotes it: recorded with who, when, why; it becomes active.
  repo.promote(land, "qa.jensen", "field recalibration after shipping damage check",
               kT0FieldRuns + 4000);
  const ActiveCalibration a = repo.active_params("FOG-3");
  EXPECT_EQ(a.run.run_id, land);
  EXPECT_EQ(a.run.promoted_by, "qa.jensen");
  EXPECT_EQ(a.run.promote_reason, "field recalibration after shipping damage check");
  EXPECT_EQ(a.run.promoted_at_ms, kT0FieldRuns + 4000);
  EXPECT_EQ(a.active.method, Method::kAins);
  EXPECT_EQ(a.active.params.to_vector(),
            test::seeded_calibration(11, Method::kAins, false).params.to_vector());
  // A newer factory PASS wins again.
  const RunId fac2 = repo.create_run(test::new_run("FOG-3", kT0FieldRuns + 5000));
  repo.finish_run(fac2, test::pass_completion(12, kT0FieldRuns + 6000));
  EXPECT_EQ(repo.active_params("FOG-3").run.run_id, fac2);
  // A sea run reviewed only for having AINS alone may be promoted; then it is active.
  const RunId sea =
      repo.create_run(field_run("FOG-3", kT0FieldRuns + 7000, calib::core::Setting::kSea));
  repo.finish_run(sea, sea_alone(13, kT0FieldRuns + 8000));
  repo.promote(sea, "qa.jensen", "vessel unit, no table within reach", kT0FieldRuns + 9000);
  EXPECT_EQ(repo.active_params("FOG-3").run.run_id, sea);
}

/// A land run below navigation grade on which AINS cannot hold the rests (issue #48 item 7): AINS
/// and legacy stored, their cross-check REVIEW (AINS's disagreement), legacy holding, done.
RunCompletion land_held_by_legacy(long seed, TimestampMs end) {
  RunCompletion c = land_pass(seed, end);
  c.crosscheck = CrosscheckRecord{
      Verdict::kReview, 4.0, {{"accel_bias_mps2[2]", "accel_bias_mps2[2]: too far apart"}}, {}};
  c.holding_method = Method::kLegacy;
  c.holding_reason =
      "AINS leaves 0.20 mg over the 40 rests against legacy's 0.11 mg (1.8×, "
      "limit 1.5×): the verdict and the active set rest on legacy";
  return c;
}

TEST(FieldRuns, WhereLegacyHoldsARunItsSetIsTheActiveOneAndReadsBack) {
  TempDir dir;
  const std::string path = dir.file("h.db");
  const RunCompletion held = land_held_by_legacy(31, kT0FieldRuns + 1000);
  RunId land = 0;
  {
    SqliteRepository repo(path);
    land = repo.create_run(field_run("MEMS-1", kT0FieldRuns, calib::core::Setting::kLand));
    repo.finish_run(land, held);
    repo.promote(land, "qa.jensen", "hand-placed field calibration", kT0FieldRuns + 2000);
  }
  SqliteOptions ro;
  ro.read_only = true;
  const SqliteRepository repo(path, ro);  // read back through a new connection
  const RunDetails d = repo.show(land);
  EXPECT_EQ(d.run.state, RunState::kDone);
  EXPECT_EQ(d.run.verdict, RunVerdict::kPass);
  EXPECT_EQ(d.run.crosscheck_verdict, Verdict::kReview);
  EXPECT_EQ(d.run.holding_method, Method::kLegacy);
  EXPECT_EQ(d.run.holding_reason, held.holding_reason);
  const ActiveCalibration a = repo.active_params("MEMS-1");
  EXPECT_EQ(a.run.run_id, land);
  EXPECT_EQ(a.active.method, Method::kLegacy);
  EXPECT_EQ(a.active.params.to_vector(),
            test::seeded_calibration(31, Method::kLegacy, false).params.to_vector());
  EXPECT_EQ(a.all.size(), 2u);
  const nlohmann::json params = active_params_json(a);
  EXPECT_EQ(params.at("source").at("method"), "legacy");
  EXPECT_EQ(params.at("source").at("holding_reason"), held.holding_reason);
  EXPECT_EQ(run_json(d.run).at("holding_method"), "legacy");
  EXPECT_EQ(repo.integrity_check(), "ok");
}

TEST(FieldRuns, OnlyALandRunWithItsLegacySetCanRestOnLegacy) {
  TempDir dir;
  SqliteRepository repo(dir.file("h.db"));
  // A factory run cannot: its pair is AINS + NLSQ.
  const RunId fac = repo.create_run(test::new_run("MEMS-2", kT0FieldRuns));
  RunCompletion f = test::pass_completion(40, kT0FieldRuns + 1);
  f.holding_method = Method::kLegacy;
  EXPECT_NE(expect_throw_message<Conflict>([&] {
              repo.finish_run(fac, f);
            }).find("legacy can hold only a land run"),
            std::string::npos);
  // A land run without its legacy set cannot.
  const RunId land =
      repo.create_run(field_run("MEMS-2", kT0FieldRuns + 10, calib::core::Setting::kLand));
  RunCompletion no_legacy = land_held_by_legacy(41, kT0FieldRuns + 20);
  no_legacy.calibrations.pop_back();
  no_legacy.state = RunState::kReview;
  no_legacy.reason = "limits: legacy missing";
  EXPECT_THROW(repo.finish_run(land, no_legacy), Conflict);
  // Where AINS holds, a REVIEW cross-check still cannot end done, as before.
  RunCompletion ains_holds = land_held_by_legacy(42, kT0FieldRuns + 20);
  ains_holds.holding_method = Method::kAins;
  EXPECT_NE(expect_throw_message<Conflict>([&] {
              repo.finish_run(land, ains_holds);
            }).find("a PASS cross-check (it is REVIEW)"),
            std::string::npos);
  // Nothing was stored by the refusals; the run can still end, on legacy.
  EXPECT_EQ(repo.show(land).run.state, RunState::kPreparing);
  repo.finish_run(land, land_held_by_legacy(43, kT0FieldRuns + 30));
  EXPECT_EQ(repo.show(land).run.holding_method, Method::kLegacy);
  // On legacy, review needs a reason of its own (its limits): the cross-check's is not one.
  const RunId land2 =
      repo.create_run(field_run("MEMS-2", kT0FieldRuns + 40, calib::core::Setting::kLand));
  RunCompletion review = land_held_by_legacy(44, kT0FieldRuns + 50);
  review.state = RunState::kReview;
  EXPECT_THROW(repo.finish_run(land2, review), InvalidInput);
  review.reasons = {{"limits", "limits: legacy: gyro_M[0][0] outside its envelope"}};
  repo.finish_run(land2, review);
  EXPECT_EQ(repo.show(land2).run.reasons.size(), 1u);
}

TEST(FieldRuns, PromotionIsRefusedWhereItMakesNoSense) {
  TempDir dir;
  SqliteRepository repo(dir.file("h.db"));
  const RunId fac = repo.create_run(test::new_run("FOG-4", kT0FieldRuns));
  repo.finish_run(fac, test::pass_completion(20, kT0FieldRuns + 1000));
  EXPECT_NE(expect_throw_message<Conflict>([&] {
              repo.promote(fac, "qa", "x", kT0FieldRuns + 2);
            }).find("factory run"),
            std::string::npos);
  const RunId live =
      repo.create_run(field_run("FOG-4", kT0FieldRuns + 10, calib::core::Setting::kLand));
  EXPECT_NE(expect_throw_message<Conflict>([&] {
              repo.promote(live, "qa", "x", kT0FieldRuns + 20);
            }).find("still preparing"),
            std::string::npos);
  RunCompletion rev = land_pass(21, kT0FieldRuns + 30);
  rev.state = RunState::kReview;
  rev.crosscheck = CrosscheckRecord{Verdict::kReview, 4.0, {{"gyro_M[1][1]", "too far apart"}}, {}};
  repo.finish_run(live, rev);
  EXPECT_NE(expect_throw_message<Conflict>([&] {
              repo.promote(live, "qa", "x", kT0FieldRuns + 40);
            }).find("only a done (PASS) field run"),
            std::string::npos);
  EXPECT_THROW(repo.promote(live, "qa", "", kT0FieldRuns + 40), InvalidInput);
  EXPECT_THROW(repo.promote(99999, "qa", "x", kT0FieldRuns + 40), NotFound);
  // Nothing was promoted: the factory run is still active.
  EXPECT_EQ(repo.active_params("FOG-4").run.run_id, fac);
}

TEST(FieldRuns, VersionThreeDatabaseMigratesKeepingItsCalibrations) {
  TempDir dir;
  const std::string path = dir.file("v3.db");
  {
    sqlite3* raw = nullptr;
    ASSERT_EQ(sqlite3_open(path.c_str(), &raw), SQLITE_OK);
    const std::vector<schema::Migration> v3(schema::migrations().begin(),
                                            schema::migrations().begin() + 3);
    schema::migrate(raw, path, v3);
    const char* sql =
        "INSERT INTO units (serial, first_seen_ms) VALUES ('OLD-3', 1714560000000);"
        "INSERT INTO runs (unit_id, operator, station, sequence_name, sequence_sha256, "
        "software_version, started_at_ms, ended_at_ms, state) VALUES "
        "(1, 'op', 'st', 'short', '', '0.1.0', 1714560000000, 1714560060000, 'review');"
        "INSERT INTO calibrations (run_id, method, params_json, sigma_json, converged, "
        "iterations, runtime_s) VALUES (1, 'ains', '{}', '{}', 1, 3, 0.5);";
    ASSERT_EQ(sqlite3_exec(raw, sql, nullptr, nullptr, nullptr), SQLITE_OK) << sqlite3_errmsg(raw);
    // v3 refuses a legacy result: the CHECK the migration widens.
    EXPECT_NE(sqlite3_exec(raw,
                           "INSERT INTO calibrations (run_id, method, params_json, sigma_json, "
                           "converged, iterations, runtime_s) VALUES (1, 'legacy', '{}', '{}', 1, "
                           "3, 0.5);",
                           nullptr, nullptr, nullptr),
              SQLITE_OK);
    sqlite3_close(raw);
  }
  SqliteRepository repo(path);
  EXPECT_EQ(repo.schema_version(), schema::kSchemaVersion);
  const auto runs = repo.history("OLD-3");
  ASSERT_EQ(runs.size(), 1u);
  EXPECT_EQ(runs[0].setting, calib::core::Setting::kFactory);
  EXPECT_FALSE(runs[0].promoted_at_ms.has_value());
  EXPECT_EQ(repo.integrity_check(), "ok");
  // The old calibration row survived the table rebuild (read back through the raw file).
  sqlite3* raw = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &raw), SQLITE_OK);
  sqlite3_stmt* st = nullptr;
  sqlite3_prepare_v2(raw, "SELECT method, iterations FROM calibrations", -1, &st, nullptr);
  ASSERT_EQ(sqlite3_step(st), SQLITE_ROW);
  EXPECT_STREQ(reinterpret_cast<const char*>(sqlite3_column_text(st, 0)), "ains");
  EXPECT_EQ(sqlite3_column_int(st, 1), 3);
  sqlite3_finalize(st);
  sqlite3_close(raw);
}

// Issue #19 item 3: an imported factory archive is active only once QA promotes it, and the
// history finds a run by its archive's SHA-256 (the import's duplicate check).
TEST(FieldRuns, AnImportedFactoryRunIsActiveOnlyWhenPromotedAndIsFoundByItsArchiveHash) {
  TempDir dir;
  SqliteRepository repo(dir.file("h.db"));
  const RunId station = repo.create_run(test::new_run("NAV-1", kT0FieldRuns));
  repo.finish_run(station, test::pass_completion(1, kT0FieldRuns + 1000));
  const RunId imported =
      repo.create_run(field_run("NAV-1", kT0FieldRuns + 5000, calib::core::Setting::kFactory));
  RunCompletion c = test::pass_completion(2, kT0FieldRuns + 6000);
  repo.finish_run(imported, c);
  EXPECT_EQ(repo.active_params("NAV-1").run.run_id, station)
      << "a later imported PASS is not active";
  const std::string msg = expect_throw_message<Conflict>(
      [&] { repo.promote(station, "qa", "why not", kT0FieldRuns + 7000); });
  EXPECT_NE(msg.find("factory run of this station"), std::string::npos) << msg;
  repo.promote(imported, "qa", "golden unit", kT0FieldRuns + 8000);
  EXPECT_EQ(repo.active_params("NAV-1").run.run_id, imported);

  const auto found = repo.runs_with_archive_sha256(c.archive_sha256);
  ASSERT_EQ(found.size(), 1u);
  EXPECT_EQ(found[0].run_id, imported);
  EXPECT_TRUE(repo.runs_with_archive_sha256(std::string(64, 'e')).empty());
  EXPECT_THROW(repo.runs_with_archive_sha256("not-a-hash"), InvalidInput);
}

}  // namespace
}  // namespace imucal::db
