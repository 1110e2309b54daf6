// Calibration-history repository on real SQLite files: history order, the active calibration rule
// (latest done+PASS run, AINS set), show() round trip, the run life cycle, start-up recovery,
// serial-number rules, read-only mode and the time text helpers.
#include "db/history/repository.hpp"

#include <gtest/gtest.h>
#include <sqlite3.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <functional>
#include <thread>

#include "db/history/serial_number.hpp"
#include "db/history/sqlite_fleet_stats.hpp"
#include "db/history/sqlite_repository.hpp"
#include "tests/db/history_fixtures.hpp"

namespace imucal::db {
using namespace imucal::db::history;
namespace {

using test::expect_throw_message;
using test::TempDir;

constexpr TimestampMs kT0Repository = 1714560000000;  // 2024-05-01T10:40:00Z
constexpr TimestampMs kMinute = 60000;

void expect_params_equal(const calib::core::ParamSet& a, const calib::core::ParamSet& b) {
  const calib::core::ParamVector va = a.to_vector(), vb = b.to_vector();
  for (int i = 0; i < calib::core::ParamSet::kSize; ++i)
    EXPECT_EQ(va(i), vb(i)) << "parameter " << calib::core::param_info(i).name;
}

std::vector<RunId> ids_of(const std::vector<RunRecord>& runs) {
  std::vector<RunId> ids;
  for (const auto& r : runs) ids.push_back(r.run_id);
  return ids;
}

TEST(Repository, HistoryOfTwoSerialsIsNewestFirstWithIdTieBreak) {
  TempDir dir;
  SqliteRepository repo(dir.file("history.db"));
  struct Made {
    RunId id;
    std::string serial;
    TimestampMs t;
  };
  std::vector<Made> made;
  // Interleaved serials, start times deliberately not in creation order, and one tie (A: two
  // runs at kT0 + 5 min, which must come out by id, newest id first).
  const std::vector<std::pair<std::string, TimestampMs>> plan = {
      {"SIM-A", kT0Repository + 5 * kMinute}, {"SIM-B", kT0Repository + 1 * kMinute},
      {"SIM-A", kT0Repository + 2 * kMinute}, {"SIM-A", kT0Repository + 9 * kMinute},
      {"SIM-B", kT0Repository + 7 * kMinute}, {"SIM-A", kT0Repository + 5 * kMinute},
      {"SIM-B", kT0Repository + 3 * kMinute}, {"SIM-A", kT0Repository + 0 * kMinute}};
  long seed = 1;
  for (const auto& [serial, t] : plan) {
    const RunId id = repo.create_run(test::new_run(serial, t));
    repo.finish_run(id, test::pass_completion(seed++, t + kMinute));
    made.push_back({id, serial, t});
  }
  // Ids are issued increasing.
  for (std::size_t i = 1; i < made.size(); ++i) EXPECT_GT(made[i].id, made[i - 1].id);

  for (const std::string serial : {"SIM-A", "SIM-B"}) {
    std::vector<Made> expected;
    for (const auto& m : made)
      if (m.serial == serial) expected.push_back(m);
    std::sort(expected.begin(), expected.end(),
              [](const Made& a, const Made& b) { return a.t != b.t ? a.t > b.t : a.id > b.id; });
    const auto hist = repo.history(serial);
    ASSERT_EQ(hist.size(), expected.size()) << serial;
    for (std::size_t i = 0; i < hist.size(); ++i) {
      EXPECT_EQ(hist[i].run_id, expected[i].id) << serial << " position " << i;
      EXPECT_EQ(hist[i].serial, serial);
      EXPECT_EQ(hist[i].started_at_ms, expected[i].t);
      EXPECT_EQ(hist[i].state, RunState::kDone);
      ASSERT_TRUE(hist[i].verdict.has_value());
      EXPECT_EQ(*hist[i].verdict, RunVerdict::kPass);
      EXPECT_EQ(hist[i].crosscheck_verdict, Verdict::kPass);
    }
    const auto top2 = repo.history(serial, 2);
    ASSERT_EQ(top2.size(), 2u);
    EXPECT_EQ(top2[0].run_id, expected[0].id);
    EXPECT_EQ(top2[1].run_id, expected[1].id);
  }
  // The tie: the two SIM-A runs at +5 min are the first (created) and sixth made.
  const auto a = repo.history("SIM-A");
  const auto ids_a = ids_of(a);
  const auto p0 = std::find(ids_a.begin(), ids_a.end(), made[0].id) - ids_a.begin();
  const auto p5 = std::find(ids_a.begin(), ids_a.end(), made[5].id) - ids_a.begin();
  EXPECT_EQ(p5 + 1, p0) << "equal start times: higher id first";

  EXPECT_THROW(repo.history("SIM-C"), NotFound);
  const std::string msg = expect_throw_message<NotFound>([&] { repo.history("SIM-C"); });
  EXPECT_NE(msg.find("SIM-C"), std::string::npos) << msg;
}

TEST(Repository, ActiveParamsIsLatestPassAndALaterReviewDoesNotReplaceIt) {
  TempDir dir;
  SqliteRepository repo(dir.file("active.db"));
  // SIM-A: PASS(seed 11) at t0, PASS(seed 12) at t0+10, REVIEW(seed 13) at t0+20, failed at
  // t0+30, interrupted at t0+40, and a PASS(seed 14) created last but started at t0+5 (older).
  const RunId r11 = repo.create_run(test::new_run("SIM-A", kT0Repository));
  repo.finish_run(r11, test::pass_completion(11, kT0Repository + kMinute));
  const RunId r12 = repo.create_run(test::new_run("SIM-A", kT0Repository + 10 * kMinute));
  repo.finish_run(r12, test::pass_completion(12, kT0Repository + 11 * kMinute));
  const RunId r13 = repo.create_run(test::new_run("SIM-A", kT0Repository + 20 * kMinute));
  repo.finish_run(r13, test::review_completion(13, kT0Repository + 21 * kMinute));
  const RunId rf = repo.create_run(test::new_run("SIM-A", kT0Repository + 30 * kMinute));
  repo.update_run_state(rf, RunState::kRunning);
  repo.update_run_state(rf, RunState::kFailed, "turntable fault 17 during step 3/12");
  const RunId ri =
      repo.create_run(test::new_run("SIM-A", kT0Repository + 40 * kMinute, RunState::kRunning));
  repo.mark_interrupted_runs(kT0Repository + 50 * kMinute);
  const RunId r14 = repo.create_run(test::new_run("SIM-A", kT0Repository + 5 * kMinute));
  repo.finish_run(r14, test::pass_completion(14, kT0Repository + 6 * kMinute));
  (void)r11;
  (void)ri;

  const ActiveCalibration a = repo.active_params("SIM-A");
  EXPECT_EQ(a.run.run_id, r12);
  EXPECT_EQ(a.active.method, Method::kAins);
  expect_params_equal(a.active.params, test::seeded_params(12, 0));
  expect_params_equal(a.active.sigma, test::seeded_sigma(12, 0));
  ASSERT_EQ(a.all.size(), 2u);
  EXPECT_EQ(a.all[0].method, Method::kAins);
  EXPECT_EQ(a.all[1].method, Method::kNlsq);
  expect_params_equal(a.all[1].params, test::seeded_params(12, 1));

  // SIM-B has only a REVIEW run: no active calibration, and the message says so.
  const RunId rb = repo.create_run(test::new_run("SIM-B", kT0Repository));
  repo.finish_run(rb, test::review_completion(21, kT0Repository + kMinute));
  const std::string msg = expect_throw_message<NotFound>([&] { repo.active_params("SIM-B"); });
  EXPECT_NE(msg.find("has no active calibration"), std::string::npos) << msg;
  EXPECT_NE(msg.find("1 run(s)"), std::string::npos) << msg;
  EXPECT_THROW(repo.active_params("SIM-NONE"), NotFound);

  // A new PASS run becomes active at once.
  const RunId r15 = repo.create_run(test::new_run("SIM-A", kT0Repository + 60 * kMinute));
  repo.finish_run(r15, test::pass_completion(15, kT0Repository + 61 * kMinute));
  EXPECT_EQ(repo.active_params("SIM-A").run.run_id, r15);
  expect_params_equal(repo.active_params("SIM-A").active.params, test::seeded_params(15, 0));
}

TEST(Repository, ShowReturnsEverythingStored) {
  TempDir dir;
  SqliteRepository repo(dir.file("show.db"));
  NewRun nr = test::new_run("UNIT_7.b-2", kT0Repository + 123);
  nr.operator_name = "Ærø Jensen";  // UTF-8 survives
  nr.sequence_sha256 = "0123456789abcdef0123456789abcdef0123456789abcdef0123456789abcdef";
  const RunId origin = repo.create_run(test::new_run("UNIT_7.b-2", kT0Repository - kMinute));
  repo.update_run_state(origin, RunState::kAborted, "operator abort");
  nr.reprocessed_from = origin;
  const RunId id = repo.create_run(nr);
  repo.update_run_state(id, RunState::kRunning);
  repo.update_run_state(id, RunState::kCalibrating);
  // Results arrive one at a time (store_*), then the completion with the archive hash.
  CalibrationRecord ains = test::seeded_calibration(4, Method::kAins);
  CalibrationRecord nlsq = test::seeded_calibration(4, Method::kNlsq, /*with_metrics=*/false);
  repo.store_calibration(id, nlsq);
  repo.store_calibration(id, ains);
  CrosscheckRecord x{Verdict::kReview,
                     3.5,
                     {{"gyro_M[0][0]", "gyro_M[0][0]: |Δ| = 30 ppm > 3.5σ bound 12 ppm"},
                      {"accel_rmse_ug", "NLSQ accel RMSE 55 µg > 40 µg, \"limit\""}},
                     {}};
  repo.store_crosscheck(id, x);
  RunCompletion c;
  c.state = RunState::kReview;
  c.ended_at_ms = kT0Repository + 999;
  c.archive_path = "/data/runs/42";
  c.archive_sha256 = std::string(64, 'f');
  repo.finish_run(id, c);

  const RunDetails d = repo.show(id);
  EXPECT_EQ(d.run.run_id, id);
  EXPECT_EQ(d.run.serial, nr.serial);
  EXPECT_EQ(d.run.operator_name, nr.operator_name);
  EXPECT_EQ(d.run.station, nr.station);
  EXPECT_EQ(d.run.sequence_name, nr.sequence_name);
  EXPECT_EQ(d.run.sequence_sha256, nr.sequence_sha256);
  EXPECT_EQ(d.run.software_version, nr.software_version);
  EXPECT_EQ(d.run.started_at_ms, nr.started_at_ms);
  ASSERT_TRUE(d.run.ended_at_ms.has_value());
  EXPECT_EQ(*d.run.ended_at_ms, kT0Repository + 999);
  EXPECT_EQ(d.run.state, RunState::kReview);
  // In review by the cross-check alone: its failures are the run's reason (issue #19 item 2).
  EXPECT_EQ(d.run.failure_reason,
            "cross-check REVIEW: " + x.failures[0].detail + "; " + x.failures[1].detail);
  ASSERT_EQ(d.run.reasons.size(), 1u);
  EXPECT_EQ(d.run.reasons[0].source, "cross-check");
  EXPECT_EQ(d.run.archive_path, "/data/runs/42");
  EXPECT_EQ(d.run.archive_sha256, std::string(64, 'f'));
  ASSERT_TRUE(d.run.reprocessed_from.has_value());
  EXPECT_EQ(*d.run.reprocessed_from, origin);
  ASSERT_TRUE(d.run.verdict.has_value());
  EXPECT_EQ(*d.run.verdict, RunVerdict::kReview);
  EXPECT_EQ(d.run.crosscheck_verdict, Verdict::kReview);

  ASSERT_EQ(d.calibrations.size(), 2u);
  const CalibrationRecord& a = d.calibrations[0];
  EXPECT_EQ(a.method, Method::kAins);  // ains first regardless of store order
  expect_params_equal(a.params, ains.params);
  expect_params_equal(a.sigma, ains.sigma);
  EXPECT_EQ(a.converged, ains.converged);
  EXPECT_EQ(a.iterations, ains.iterations);
  EXPECT_EQ(a.runtime_s, ains.runtime_s);
  EXPECT_EQ(a.warnings, ains.warnings);
  ASSERT_TRUE(a.metrics.has_value());
  EXPECT_EQ(a.metrics->orientation_rmse_mdeg, ains.metrics->orientation_rmse_mdeg);
  EXPECT_EQ(a.metrics->accel_rmse_ug, ains.metrics->accel_rmse_ug);
  EXPECT_EQ(a.metrics->heading_offset_gamma_np_rad, ains.metrics->heading_offset_gamma_np_rad);
  EXPECT_EQ(a.metrics->body_misalignment_theta_bp_rad,
            ains.metrics->body_misalignment_theta_bp_rad);
  EXPECT_EQ(d.calibrations[1].method, Method::kNlsq);
  expect_params_equal(d.calibrations[1].params, nlsq.params);
  EXPECT_FALSE(d.calibrations[1].metrics.has_value());

  ASSERT_TRUE(d.crosscheck.has_value());
  EXPECT_EQ(d.crosscheck->verdict, Verdict::kReview);
  EXPECT_EQ(d.crosscheck->k_sigma, 3.5);
  ASSERT_EQ(d.crosscheck->failures.size(), 2u);
  EXPECT_EQ(d.crosscheck->failures[1].term, "accel_rmse_ug");
  EXPECT_EQ(d.crosscheck->failures[1].detail, x.failures[1].detail);

  EXPECT_THROW(repo.show(id + 1000), NotFound);
}

// Issue #19 item 2: before schema v5 every view showed the cross-check's verdict as the run's, so a
// run the gap check, the limits or a partial archive had sent to review read "PASS".
TEST(Repository, TheRunVerdictFollowsTheStateWithEveryReasonNotTheCrossCheckAlone) {
  TempDir dir;
  SqliteRepository repo(dir.file("verdict.db"));
  // Cross-check PASS, but the limits and the gap say review.
  const RunId review = repo.create_run(test::new_run("SIM-V", kT0Repository));
  RunCompletion c = test::pass_completion(1, kT0Repository + kMinute);
  c.state = RunState::kReview;
  c.reasons = {{"limits", "limits: gyro bias z 0.31 deg/h > 0.2 deg/h"},
               {"gap", "sim-to-real gap: explained by gyro_g_sensitivity"}};
  repo.finish_run(review, c);
  const RunId failed = repo.create_run(test::new_run("SIM-V", kT0Repository + 2 * kMinute));
  repo.update_run_state(failed, RunState::kAborted, "aborted by operator");
  const RunId done = repo.create_run(test::new_run("SIM-V", kT0Repository + 4 * kMinute));
  repo.finish_run(done, test::pass_completion(2, kT0Repository + 5 * kMinute));
  const RunId live = repo.create_run(test::new_run("SIM-V", kT0Repository + 6 * kMinute));

  const RunRecord r = repo.show(review).run;
  EXPECT_EQ(r.verdict, RunVerdict::kReview);
  EXPECT_EQ(r.crosscheck_verdict, Verdict::kPass) << "the cross-check's own result stays beside it";
  ASSERT_EQ(r.reasons.size(), 2u);
  EXPECT_EQ(r.reasons[0], (RunReason{"limits", "limits: gyro bias z 0.31 deg/h > 0.2 deg/h"}));
  EXPECT_EQ(r.reasons[1].source, "gap");
  EXPECT_EQ(r.failure_reason,
            "limits: gyro bias z 0.31 deg/h > 0.2 deg/h; sim-to-real gap: explained by "
            "gyro_g_sensitivity");
  const RunRecord a = repo.show(failed).run;
  EXPECT_EQ(a.verdict, RunVerdict::kAborted) << "an operator's abort is not the unit's FAILED";
  EXPECT_EQ(a.reasons, (std::vector<RunReason>{{"aborted", "aborted by operator"}}));
  EXPECT_EQ(repo.show(done).run.verdict, RunVerdict::kPass);
  EXPECT_TRUE(repo.show(done).run.reasons.empty());
  EXPECT_FALSE(repo.show(live).run.verdict.has_value());
  // History and export say the same as show.
  for (const RunRecord& h : repo.history("SIM-V"))
    EXPECT_EQ(h.verdict, repo.show(h.run_id).run.verdict) << "run " << h.run_id;
  repo.export_rows({}, [&](const ExportRow& row) {
    EXPECT_EQ(row.run.verdict, repo.show(row.run.run_id).run.verdict) << row.run.run_id;
  });
  // Only the PASS run is active, and a done run cannot carry reasons against it.
  EXPECT_EQ(repo.active_params("SIM-V").run.run_id, done);
  RunCompletion contradictory = test::pass_completion(3, kT0Repository + 7 * kMinute);
  contradictory.reasons = {{"gap", "sim-to-real gap"}};
  EXPECT_THROW(repo.finish_run(live, contradictory), InvalidInput);
}

TEST(Repository, LifeCycleRulesAreEnforcedAndARefusedFinishWritesNothing) {
  TempDir dir;
  SqliteRepository repo(dir.file("life.db"));
  const RunId id = repo.create_run(test::new_run("SIM-0001", kT0Repository));
  repo.update_run_state(id, RunState::kCalibrating);
  EXPECT_THROW(repo.update_run_state(id, RunState::kRunning), Conflict);  // backwards
  repo.update_run_state(id, RunState::kCalibrating);                      // same: no-op

  // done with only one method and no cross-check: refused, and the ains row rolled back.
  RunCompletion partial;
  partial.state = RunState::kDone;
  partial.ended_at_ms = kT0Repository + kMinute;
  partial.calibrations = {test::seeded_calibration(1, Method::kAins)};
  const std::string msg = expect_throw_message<Conflict>([&] { repo.finish_run(id, partial); });
  EXPECT_NE(msg.find("nlsq calibration"), std::string::npos) << msg;
  EXPECT_NE(msg.find("cross-check"), std::string::npos) << msg;
  RunDetails d = repo.show(id);
  EXPECT_EQ(d.run.state, RunState::kCalibrating);
  EXPECT_TRUE(d.calibrations.empty()) << "refused finish_run must not leave rows behind";

  // A REVIEW verdict cannot make a done run; a PASS verdict cannot go to review.
  RunCompletion wrong = test::review_completion(2, kT0Repository + kMinute);
  wrong.state = RunState::kDone;
  EXPECT_THROW(repo.finish_run(id, wrong), Conflict);
  RunCompletion wrong2 = test::pass_completion(2, kT0Repository + kMinute);
  wrong2.state = RunState::kReview;
  EXPECT_THROW(repo.finish_run(id, wrong2), Conflict);
  // failed needs a reason; a non-terminal completion state is invalid.
  RunCompletion failed;
  failed.state = RunState::kFailed;
  failed.ended_at_ms = kT0Repository + kMinute;
  EXPECT_THROW(repo.finish_run(id, failed), InvalidInput);
  RunCompletion live;
  live.state = RunState::kRunning;
  EXPECT_THROW(repo.finish_run(id, live), InvalidInput);
  // Bad values: NaN parameter, negative sigma, bad SHA-256.
  CalibrationRecord nan_cal = test::seeded_calibration(3, Method::kAins);
  nan_cal.params.gyro_M(1, 2) = std::nan("");
  EXPECT_THROW(repo.store_calibration(id, nan_cal), InvalidInput);
  CalibrationRecord neg_sigma = test::seeded_calibration(3, Method::kAins);
  neg_sigma.sigma.accel_bias_mps2(0) = -1e-6;
  EXPECT_THROW(repo.store_calibration(id, neg_sigma), InvalidInput);
  RunCompletion bad_sha = test::pass_completion(3, kT0Repository + kMinute);
  bad_sha.archive_sha256 = "ABC";
  EXPECT_THROW(repo.finish_run(id, bad_sha), InvalidInput);
  EXPECT_TRUE(repo.show(id).calibrations.empty());

  // Duplicate method: Conflict.
  repo.store_calibration(id, test::seeded_calibration(5, Method::kNlsq));
  EXPECT_THROW(repo.store_calibration(id, test::seeded_calibration(6, Method::kNlsq)), Conflict);

  // Finish properly (the nlsq stored before counts), then the run is final.
  RunCompletion ok = test::pass_completion(5, kT0Repository + 2 * kMinute);
  ok.calibrations = {test::seeded_calibration(5, Method::kAins)};
  repo.finish_run(id, ok);
  d = repo.show(id);
  EXPECT_EQ(d.run.state, RunState::kDone);
  EXPECT_EQ(d.calibrations.size(), 2u);
  EXPECT_THROW(repo.update_run_state(id, RunState::kRunning), Conflict);
  EXPECT_THROW(repo.update_run_state(id, RunState::kAborted, "late abort"), Conflict);
  EXPECT_THROW(repo.store_crosscheck(id, CrosscheckRecord{Verdict::kPass, 4.0, {}, {}}), Conflict);
  EXPECT_THROW(repo.finish_run(id, ok), Conflict);

  // Unknown runs and bad new runs.
  EXPECT_THROW(repo.update_run_state(9999, RunState::kRunning), NotFound);
  EXPECT_THROW(repo.store_calibration(9999, test::seeded_calibration(1, Method::kAins)), NotFound);
  NewRun dangling = test::new_run("SIM-0001", kT0Repository);
  dangling.reprocessed_from = 9999;
  EXPECT_THROW(repo.create_run(dangling), NotFound);
  EXPECT_THROW(repo.create_run(test::new_run("SIM-0001", kT0Repository, RunState::kDone)),
               InvalidInput);
  NewRun bad_seq = test::new_run("SIM-0001", kT0Repository);
  bad_seq.sequence_sha256 = std::string(64, 'G');
  EXPECT_THROW(repo.create_run(bad_seq), InvalidInput);
  EXPECT_EQ(repo.history("SIM-0001").size(), 1u) << "refused create_run must not add a run";
}

TEST(Repository, MarkInterruptedRunsTurnsEveryLiveRunIntoInterrupted) {
  TempDir dir;
  const std::string path = dir.file("recover.db");
  std::vector<RunId> live;
  RunId done = 0;
  {
    SqliteRepository repo(path);
    live.push_back(repo.create_run(test::new_run("SIM-1", kT0Repository)));  // preparing
    live.push_back(
        repo.create_run(test::new_run("SIM-2", kT0Repository, RunState::kRunning)));  // running
    const RunId cal = repo.create_run(test::new_run("SIM-3", kT0Repository, RunState::kRunning));
    repo.update_run_state(cal, RunState::kCalibrating);
    repo.store_calibration(cal, test::seeded_calibration(8, Method::kAins));  // partial results
    live.push_back(cal);
    done = repo.create_run(test::new_run("SIM-1", kT0Repository + kMinute));
    repo.finish_run(done, test::pass_completion(9, kT0Repository + 2 * kMinute));
    EXPECT_EQ(ids_of(repo.runs_in_state(live_states())), live);
  }  // "daemon dies": the connection closes without any cleanup
  SqliteRepository repo(path);
  const std::vector<RunId> marked = repo.mark_interrupted_runs(kT0Repository + 10 * kMinute);
  EXPECT_EQ(marked, live);
  for (RunId id : live) {
    const RunDetails d = repo.show(id);
    EXPECT_EQ(d.run.state, RunState::kInterrupted);
    ASSERT_TRUE(d.run.ended_at_ms.has_value());
    EXPECT_EQ(*d.run.ended_at_ms, kT0Repository + 10 * kMinute);
    EXPECT_NE(d.run.failure_reason.find("found at start-up"), std::string::npos);
  }
  EXPECT_NE(repo.show(live[2]).run.failure_reason.find("calibrating"), std::string::npos);
  EXPECT_EQ(repo.show(live[2]).calibrations.size(), 1u) << "results stored so far are kept";
  EXPECT_EQ(repo.show(done).run.state, RunState::kDone);
  EXPECT_TRUE(repo.runs_in_state(live_states()).empty());
  EXPECT_EQ(ids_of(repo.runs_in_state({RunState::kInterrupted, RunState::kDone})),
            (std::vector<RunId>{live[0], live[1], live[2], done}));
  EXPECT_TRUE(repo.mark_interrupted_runs(kT0Repository + 11 * kMinute).empty()) << "idempotent";
}

struct BadSerial {
  std::string serial;
  std::string hint;  // what the message must name
};

class InvalidSerialTest : public ::testing::TestWithParam<BadSerial> {};

TEST_P(InvalidSerialTest, RefusedWithTheRuleAndNothingWritten) {
  TempDir dir;
  SqliteRepository repo(dir.file("serial.db"));
  const BadSerial& bad = GetParam();
  ASSERT_TRUE(serial_problem(bad.serial).has_value());
  const std::string msg = expect_throw_message<InvalidInput>(
      [&] { repo.create_run(test::new_run(bad.serial, kT0Repository)); });
  EXPECT_NE(msg.find(bad.hint), std::string::npos) << msg;
  EXPECT_NE(msg.find(kSerialRule), std::string::npos) << msg;
  EXPECT_EQ(msg.find('\n'), std::string::npos) << "control characters are escaped: " << msg;
  EXPECT_THROW(repo.history(bad.serial), InvalidInput);
  EXPECT_THROW(repo.active_params(bad.serial), InvalidInput);
  EXPECT_TRUE(repo.runs_in_state(live_states()).empty());
}

INSTANTIATE_TEST_SUITE_P(
    Serials, InvalidSerialTest,
    ::testing::Values(BadSerial{"", "empty"}, BadSerial{std::string(33, 'A'), "too long: 33"},
                      BadSerial{"SIM 0001", "a space at position 4"},
                      BadSerial{"SIM\n0001", "control character 0x0a at position 4"},
                      BadSerial{std::string("SIM\x01", 4), "control character 0x01"},
                      BadSerial{"SIM/0001", "'/' (path separator)"},
                      BadSerial{"../etc", "'/' (path separator)"},
                      BadSerial{"-rf", "must start with a letter or digit"},
                      BadSerial{".hidden", "must start with a letter or digit"},
                      BadSerial{"SIM\xc3\xa6", "non-ASCII byte 0xc3"},
                      BadSerial{"SIM;DROP", "';' at position 4"}));

TEST(SerialNumber, AcceptsTheDocumentedAlphabetAndLength) {
  const std::vector<std::string> good = {
      "SIM-0001", "a", "0", "Unit_7.b-2", std::string(32, 'Z'), "abc-XYZ_0189.a"};
  for (const std::string& s : good)
    EXPECT_FALSE(serial_problem(s).has_value()) << s << ": " << serial_problem(s).value_or("");
  TempDir dir;
  SqliteRepository repo(dir.file("ok.db"));
  // The database's own CHECK constraint agrees with the code on the edge cases.
  for (const std::string& s : {std::string("abc-XYZ_0189.a"), std::string(32, 'Z')}) {
    repo.create_run(test::new_run(s, kT0Repository));
    EXPECT_EQ(repo.history(s).size(), 1u);
  }
  EXPECT_EQ(kSerialMaxLength, 32u);
}

TEST(Repository, DatabaseCheckConstraintRejectsBadSerialsWrittenAroundTheCode) {
  TempDir dir;
  const std::string path = dir.file("check.db");
  { SqliteRepository repo(path); }
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  for (const char* bad : {"A B", "A/B", "-AB", ""}) {
    sqlite3_stmt* st = nullptr;
    ASSERT_EQ(sqlite3_prepare_v2(db, "INSERT INTO units (serial, first_seen_ms) VALUES (?1, 0)", -1,
                                 &st, nullptr),
              SQLITE_OK);
    sqlite3_bind_text(st, 1, bad, -1, SQLITE_TRANSIENT);
    EXPECT_EQ(sqlite3_step(st), SQLITE_CONSTRAINT) << "serial \"" << bad << "\"";
    sqlite3_finalize(st);
  }
  sqlite3_close(db);
}

TEST(Repository, ReadOnlyModeRefusesWritesAndSeesCommittedDataWhileAWriterHoldsTheLock) {
  TempDir dir;
  const std::string path = dir.file("ro.db");
  SqliteRepository writer(path);
  const RunId committed = writer.create_run(test::new_run("SIM-RO", kT0Repository));
  writer.finish_run(committed, test::pass_completion(31, kT0Repository + kMinute));

  // Another process-like connection holds an open write transaction with an uncommitted run.
  sqlite3* raw = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &raw), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(raw,
                         "BEGIN IMMEDIATE; INSERT INTO runs (unit_id, operator, station, "
                         "sequence_name, sequence_sha256, software_version, started_at_ms, state) "
                         "SELECT id, 'x', 'x', 'x', '', 'x', 1, 'running' FROM units;",
                         nullptr, nullptr, nullptr),
            SQLITE_OK);

  SqliteOptions ro_opts;
  ro_opts.read_only = true;
  SqliteRepository reader(path, ro_opts);
  EXPECT_TRUE(reader.read_only());
  const auto t0 = std::chrono::steady_clock::now();
  const auto hist = reader.history("SIM-RO");
  const double waited_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  ASSERT_EQ(hist.size(), 1u) << "sees the committed run, not the uncommitted one";
  EXPECT_EQ(hist[0].run_id, committed);
  EXPECT_LT(waited_s, 1.0) << "WAL readers do not wait for the writer";
  expect_params_equal(reader.active_params("SIM-RO").active.params, test::seeded_params(31, 0));
  EXPECT_TRUE(reader.runs_in_state(live_states()).empty());

  // Writes through the read-only repository: a clear ReadOnly error, whatever the method.
  const std::string msg = expect_throw_message<ReadOnly>(
      [&] { reader.create_run(test::new_run("SIM-RO", kT0Repository + 1)); });
  EXPECT_NE(msg.find("read-only"), std::string::npos) << msg;
  EXPECT_NE(msg.find(path), std::string::npos) << msg;
  EXPECT_THROW(reader.update_run_state(committed, RunState::kRunning), ReadOnly);
  EXPECT_THROW(reader.finish_run(committed, test::pass_completion(1, kT0Repository)), ReadOnly);
  EXPECT_THROW(reader.store_calibration(committed, test::seeded_calibration(1, Method::kAins)),
               ReadOnly);
  EXPECT_THROW(reader.store_crosscheck(committed, CrosscheckRecord{}), ReadOnly);
  EXPECT_THROW(reader.mark_interrupted_runs(kT0Repository), ReadOnly);
  EXPECT_THROW(reader.transaction([] {}), ReadOnly);

  // A second writer cannot get the lock: Busy after its busy_timeout, not a hang.
  SqliteOptions quick;
  quick.busy_timeout_ms = 100;
  SqliteRepository writer2(path, quick);
  const auto t1 = std::chrono::steady_clock::now();
  EXPECT_THROW(writer2.create_run(test::new_run("SIM-RO", kT0Repository + 2)), Busy);
  const double busy_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count();
  EXPECT_GE(busy_s, 0.09);
  EXPECT_LT(busy_s, 3.0);

  // The writer commits: a new read sees it.
  ASSERT_EQ(sqlite3_exec(raw, "COMMIT", nullptr, nullptr, nullptr), SQLITE_OK);
  sqlite3_close(raw);
  EXPECT_EQ(reader.history("SIM-RO").size(), 2u);
  EXPECT_EQ(reader.runs_in_state({RunState::kRunning}).size(), 1u);
}

TEST(Repository, ReadOnlyOpenWithTheDaemonDownAndOfAMissingFile) {
  TempDir dir;
  const std::string path = dir.file("down.db");
  {
    SqliteRepository writer(path);
    writer.create_run(test::new_run("SIM-DOWN", kT0Repository));
  }  // last connection closed: WAL checkpointed and removed
  SqliteOptions ro;
  ro.read_only = true;
  SqliteRepository reader(path, ro);
  EXPECT_EQ(reader.history("SIM-DOWN").size(), 1u);
  EXPECT_EQ(reader.integrity_check(), "ok");

  const std::string missing = dir.file("nope.db");
  const std::string msg = expect_throw_message<NotFound>([&] { SqliteRepository r(missing, ro); });
  EXPECT_NE(msg.find(missing), std::string::npos) << msg;
  EXPECT_FALSE(std::filesystem::exists(missing)) << "read-only mode never creates a file";
  SqliteOptions no_create;
  no_create.create = false;
  EXPECT_THROW(SqliteRepository r(missing, no_create), NotFound);
}

/// Runs `read` as an account that cannot write `dir`, as QA and operators read the daemon's
/// /var/lib/imucal (0755, the daemon's account): as root in a child process switched to nobody,
/// otherwise here with the directory made read-only. Returns what `read` returned, or "error: "
/// and the exception's message.
std::string read_without_write_access(const std::string& dir,
                                      const std::function<std::string()>& read) {
  const auto guarded = [&read]() -> std::string {
    try {
      return read();
    } catch (const std::exception& e) {
      return std::string("error: ") + e.what();
    }
  };
  if (::geteuid() != 0) {
    ::chmod(dir.c_str(), 0555);
    const std::string out = guarded();
    ::chmod(dir.c_str(), 0755);
    return out;
  }
  ::chmod(dir.c_str(), 0755);  // mkdtemp's 0700 would keep nobody out altogether
  int fds[2];
  if (::pipe(fds) != 0) return "error: pipe";
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::close(fds[0]);
    std::string out = "error: cannot become nobody";
    if (::setgid(65534) == 0 && ::setuid(65534) == 0) out = guarded();
    const ssize_t written = ::write(fds[1], out.data(), out.size());
    ::_exit(written == static_cast<ssize_t>(out.size()) ? 0 : 1);
  }
  ::close(fds[1]);
  std::string out;
  char buf[512];
  for (ssize_t n; (n = ::read(fds[0], buf, sizeof buf)) > 0;)
    out.append(buf, static_cast<size_t>(n));
  ::close(fds[0]);
  int status = 0;
  ::waitpid(pid, &status, 0);
  return out;
}

// The daemon stopped, its history read by an account that may not create files beside it (QA's
// stationweb, an operator's `stationctl history` falling back to the file): a WAL database can be
// read so only where its -wal and -shm files exist, so the writer keeps them when it closes. Before
// it did, every such read failed "attempt to write a readonly database".
TEST(Repository, ReadOnlyOpenWithTheDaemonDownByAnAccountThatCannotWriteTheDirectory) {
  TempDir dir;
  const std::string path = dir.file("history.sqlite");
  {
    SqliteRepository writer(path);
    writer.create_run(test::new_run("SIM-QA", kT0Repository));
  }
  EXPECT_TRUE(std::filesystem::exists(path + "-shm")) << "the writer removed its -shm on close";
  ASSERT_TRUE(std::filesystem::exists(path + "-wal")) << "the writer removed its -wal on close";
  EXPECT_EQ(std::filesystem::file_size(path + "-wal"), 0u) << "frames left beside the closed file";
  const std::string out = read_without_write_access(dir.path(), [&] {
    SqliteOptions ro;
    ro.read_only = true;
    SqliteRepository reader(path, ro);
    SqliteFleetStats stats(path);
    return std::to_string(reader.history("SIM-QA").size()) + " run, " +
           std::to_string(stats.verdict_counts_per_station(FleetFilter{}).size()) + " station";
  });
  EXPECT_EQ(out, "1 run, 1 station");
  // The writer opens the file again as before (the kept files are its own WAL).
  SqliteRepository writer(path);
  EXPECT_EQ(writer.history("SIM-QA").size(), 1u);
  EXPECT_EQ(writer.integrity_check(), "ok");
}

TEST(Repository, TransactionGroupsWritesAndRollsBackOnException) {
  TempDir dir;
  SqliteRepository repo(dir.file("tx.db"));
  EXPECT_THROW(repo.transaction([&] {
    repo.create_run(test::new_run("SIM-TX", kT0Repository));
    repo.create_run(test::new_run("SIM-TX", kT0Repository + 1));
    throw std::runtime_error("abandon import");
  }),
               std::runtime_error);
  EXPECT_THROW(repo.history("SIM-TX"), NotFound) << "not even the unit was kept";
  repo.transaction([&] {
    const RunId a = repo.create_run(test::new_run("SIM-TX", kT0Repository));
    repo.finish_run(a, test::pass_completion(1, kT0Repository + 1));
    // An inner failure (savepoint) does not abort the outer transaction.
    const RunId b = repo.create_run(test::new_run("SIM-TX", kT0Repository + 2));
    EXPECT_THROW(repo.update_run_state(b, RunState::kFailed), InvalidInput);  // no reason
  });
  EXPECT_EQ(repo.history("SIM-TX").size(), 2u);
}

TEST(Repository, ConcurrentThreadsShareOneRepository) {
  TempDir dir;
  SqliteRepository repo(dir.file("threads.db"));
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t)
    threads.emplace_back([&repo, t] {
      for (int i = 0; i < 10; ++i) {
        const std::string serial = "SIM-T" + std::to_string(t);
        const RunId id = repo.create_run(test::new_run(serial, kT0Repository + i));
        repo.finish_run(id, test::pass_completion(t * 100 + i, kT0Repository + i + 1));
        repo.history(serial);
      }
    });
  for (auto& th : threads) th.join();
  for (int t = 0; t < 4; ++t) {
    const std::string serial = "SIM-T" + std::to_string(t);
    EXPECT_EQ(repo.history(serial).size(), 10u);
    expect_params_equal(repo.active_params(serial).active.params,
                        test::seeded_params(t * 100 + 9, 0));
  }
  EXPECT_EQ(repo.integrity_check(), "ok");
}

TEST(Repository, CorruptStoredValuesAreReportedNotReturned) {
  TempDir dir;
  const std::string path = dir.file("corrupt.db");
  RunId id = 0;
  {
    SqliteRepository repo(path);
    id = repo.create_run(test::new_run("SIM-C", kT0Repository));
    repo.finish_run(id, test::pass_completion(7, kT0Repository + 1));
  }
  auto tamper = [&](const char* sql) {
    sqlite3* raw = nullptr;
    ASSERT_EQ(sqlite3_open(path.c_str(), &raw), SQLITE_OK);
    ASSERT_EQ(sqlite3_exec(raw, sql, nullptr, nullptr, nullptr), SQLITE_OK) << sqlite3_errmsg(raw);
    sqlite3_close(raw);
  };
  // Valid JSON (the CHECK allows it) of the wrong shape: accel_M row 1 has two entries.
  tamper(
      "UPDATE calibrations SET params_json = json_replace(params_json, '$.accel_M[1]', "
      "json('[1,2]')) WHERE method = 'nlsq'");
  SqliteRepository repo(path);
  std::string msg = expect_throw_message<Corrupt>([&] { repo.show(id); });
  EXPECT_NE(msg.find("accel_M[1]"), std::string::npos) << msg;
  EXPECT_NE(msg.find("nlsq params_json"), std::string::npos) << msg;
  // A negative sigma in the active set.
  tamper(
      "UPDATE calibrations SET sigma_json = json_replace(sigma_json, '$.gyro_bias_radps[2]', "
      "-1.0) WHERE method = 'ains'");
  msg = expect_throw_message<Corrupt>([&] { repo.active_params("SIM-C"); });
  EXPECT_NE(msg.find("negative"), std::string::npos) << msg;
  EXPECT_NE(msg.find("ains sigma_json"), std::string::npos) << msg;
}

TEST(Time, FormatAndParseAgainstKnownEpochValues) {
  EXPECT_EQ(format_time_utc(0), "1970-01-01T00:00:00.000Z");
  EXPECT_EQ(format_time_utc(946684800000), "2000-01-01T00:00:00.000Z");  // well-known epoch value
  EXPECT_EQ(format_time_utc(-1), "1969-12-31T23:59:59.999Z");
  EXPECT_EQ(parse_time_utc("2000-01-01"), 946684800000);
  // 2024 is a leap year: 2024-03-01 is 60 days after 2024-01-01 (= 1704067200 s, well known).
  EXPECT_EQ(parse_time_utc("2024-03-01T00:00:00Z"), (1704067200LL + 60 * 86400) * 1000);
  EXPECT_EQ(parse_time_utc("2024-05-01T12:34:56.789+02:00"),
            parse_time_utc("2024-05-01T10:34:56.789Z"));
  EXPECT_EQ(parse_time_utc("2024-05-01 10:34"), parse_time_utc("2024-05-01T10:34:00.000Z"));
  EXPECT_EQ(parse_time_utc("2024-05-01T10:34:56.7891"), parse_time_utc("2024-05-01T10:34:56.789"));
  for (TimestampMs t :
       {kT0Repository, kT0Repository + 123, TimestampMs{951782400000}, TimestampMs{-86400001}})
    EXPECT_EQ(parse_time_utc(format_time_utc(t)), t) << t;
  for (const char* bad : {"2024-02-30", "2023-02-29", "2024-13-01", "24-05-01", "2024-05-01T25:00",
                          "2024-05-01T10:00:00X", "yesterday", "", "2024-05-01T10:00+2"}) {
    const std::string msg = expect_throw_message<InvalidInput>([&] { parse_time_utc(bad); });
    EXPECT_NE(msg.find("expected YYYY-MM-DD"), std::string::npos) << bad << ": " << msg;
  }
}

// Issue #50: finish_run stores whose the end was. A failed, aborted or interrupted run may be the
// station's (STATION-FAULT); a completion's verdict its state cannot have is refused, nothing
// stored; without one the state's own is stored.
TEST(Repository, AFinishedRunStoresWhoseItsEndWasAndRefusesAVerdictItsStateCannotHave) {
  test::TempDir dir;
  SqliteRepository repo(dir.file("h.db"));
  const RunId table = repo.create_run(test::new_run("SIM-W", kT0Repository));
  RunCompletion c;
  c.state = RunState::kAborted;
  c.verdict = RunVerdict::kStationFault;
  c.ended_at_ms = kT0Repository + kMinute;
  c.reason = "table: turntable tcp:127.0.0.1:1502: cannot connect after 10 attempt(s)";
  repo.finish_run(table, c);
  EXPECT_EQ(repo.show(table).run.verdict, RunVerdict::kStationFault);

  const RunId unit = repo.create_run(test::new_run("SIM-W", kT0Repository + 2 * kMinute));
  RunCompletion wrong;
  wrong.state = RunState::kFailed;
  wrong.verdict = RunVerdict::kAborted;
  wrong.ended_at_ms = kT0Repository + 3 * kMinute;
  wrong.reason = "calibration failed: data check";
  const std::string msg =
      test::expect_throw_message<InvalidInput>([&] { repo.finish_run(unit, wrong); });
  EXPECT_NE(msg.find("a failed run cannot have the verdict ABORTED"), std::string::npos) << msg;
  EXPECT_FALSE(repo.show(unit).run.verdict.has_value()) << "nothing stored";
  wrong.verdict.reset();
  repo.finish_run(unit, wrong);
  EXPECT_EQ(repo.show(unit).run.verdict, RunVerdict::kFailed) << "the state's own: the unit's";

  const RunId pass = repo.create_run(test::new_run("SIM-W", kT0Repository + 4 * kMinute));
  RunCompletion done = test::pass_completion(3, kT0Repository + 5 * kMinute);
  done.verdict = RunVerdict::kStationFault;
  EXPECT_THROW(repo.finish_run(pass, done), InvalidInput) << "a done run is PASS";
  // Start-up recovery marks a live run INTERRUPTED: the daemon's, not the unit's.
  const std::vector<RunId> marked = repo.mark_interrupted_runs(kT0Repository + 6 * kMinute);
  ASSERT_EQ(marked, std::vector<RunId>{pass});
  EXPECT_EQ(repo.show(pass).run.verdict, RunVerdict::kInterrupted);
}

}  // namespace
}  // namespace imucal::db
