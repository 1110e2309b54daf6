// Crash recovery (issue #3): `kill -9` of stationd mid-run, then a restart. The run must be marked
// `interrupted` (never silently resumed), the database must pass PRAGMA integrity_check, the run's
// archive must be intact (readable by db::archive::read_archive, imu.csv and table.csv of equal
// length) and `reprocess` must work on it. Two moments: while the table runs the sequence (the
// archive is a prefix of the sequence) and while the daemon calibrates (the archive is complete:
// reprocessing must PASS).
#include <cmath>

#include "db/archive/run_archive.hpp"
#include "tests/e2e/station_harness.hpp"

namespace imucal::e2e {
namespace {

struct Killed {
  long long run_id = -1;
  json last_status;  ///< the live run object seen just before the kill
};

/// Starts a run, waits until `when` holds for the live run, then SIGKILLs the daemon.
Killed start_and_kill(Station& st, const std::string& serial, const std::function<bool(const json&)>& when) {
  Killed k;
  const CmdResult start = st.ctl({"--json", "run", "start", "--serial", serial, "--sequence", "short"});
  EXPECT_EQ(start.exit_code, 0) << start.describe();
  k.run_id = run_id_of(start.json_out());
  k.last_status = st.wait_live_run(when, 120s, 5ms);
  st.daemon().kill9();
  return k;
}

/// After the restart: the run is interrupted with a reason, the database is sound, the archive
/// reads back; returns the run record. `capture_complete`: whether the capture had finished when
/// the daemon died (run.toml [capture] complete).
json check_interrupted(Station& st, long long run_id, bool capture_complete) {
  // Idle after the restart: the run is not resumed.
  const auto status = st.request("run.status");
  EXPECT_TRUE(status && (*status)["ok"] == true) << (status ? status->dump() : "no reply");
  if (status) {
    EXPECT_EQ((*status)["result"].value("state", ""), "idle") << status->dump(2);
    EXPECT_TRUE((*status)["result"]["run"].is_null()) << status->dump(2);
  }
  const json shown = show_run(st, run_id);
  if (!shown.is_object()) return json();
  const json run = shown["run"];
  EXPECT_EQ(run.value("state", ""), "interrupted") << run.dump(2);
  EXPECT_FALSE(run.value("failure_reason", "").empty()) << run.dump(2);
  EXPECT_FALSE(run["ended_at"].is_null()) << run.dump(2);
  EXPECT_EQ(run.value("archive_sha256", "").size(), 64u) << "no archive digest after recovery:\n" << run.dump(2);

  {  // PRAGMA integrity_check through the repository library, not through the daemon.
    db::history::SqliteOptions o;
    o.read_only = true;
    db::history::SqliteRepository repo(st.db_path(), o);
    EXPECT_EQ(repo.integrity_check(), "ok");
    EXPECT_EQ(repo.show(run_id).run.state, db::history::RunState::kInterrupted);
  }

  const std::string dir = run.value("archive_path", "");
  for (const char* f : {"run.toml", "imu.csv", "table.csv", "capture.log"})
    EXPECT_TRUE(fs::exists(dir + "/" + f)) << dir << "/" << f << " missing after recovery";
  try {
    const db::archive::RunArchive a = db::archive::read_archive(dir);
    EXPECT_EQ(a.info.serial, run.value("serial", ""));
    EXPECT_EQ(a.imu.size(), a.table.size());
    EXPECT_GT(a.imu.size(), 1000u) << "the recovered archive lost its data";
    EXPECT_FALSE(a.info.end_time.empty()) << "recovery must write the end time";
    std::fprintf(stderr, "[e2e] recovered archive %s: %zu rows\n", dir.c_str(), a.imu.size());
  } catch (const std::exception& e) {
    ADD_FAILURE() << "archive of the interrupted run does not read back: " << e.what();
  }
  const std::string toml = read_text(dir + "/run.toml");
  EXPECT_TRUE(std::regex_search(
      toml, std::regex(capture_complete ? R"(complete\s*=\s*true)" : R"(complete\s*=\s*false)")))
      << toml;
  return run;
}

TEST(StationRecovery, KillNineWhileRunningThenRestartMarksTheRunInterruptedAndReprocessGivesAClearOutcome) {
  Station st;
  ASSERT_TRUE(st.start(SimOptions{100.0, 21, {}}));
  const Killed k = start_and_kill(st, "SIM-0300", [](const json& r) {
    return r.value("state", "") == "running" && r.value("step", 0) >= 6;
  });
  ASSERT_GT(k.run_id, 0);
  ASSERT_FALSE(k.last_status.is_null()) << "the run never reached step 6:\n" << st.daemon_log();
  std::fprintf(stderr, "[e2e] killed at %s\n", k.last_status.dump().c_str());
  ASSERT_TRUE(st.start_daemon()) << st.daemon_log();
  const json run = check_interrupted(st, k.run_id, /*capture_complete=*/false);
  ASSERT_TRUE(run.is_object());
  EXPECT_TRUE(contains_ci(run.value("failure_reason", ""), "running")) << "the reason should name the state:\n"
                                                                       << run.dump(2);

  // Reprocess: a prefix of the sequence, which must never become the unit's active parameters.
  // Refused unless asked for explicitly, naming why; then REVIEW at best.
  const CmdResult refused = st.ctl({"reprocess", std::to_string(k.run_id), "--wait"}, 60s);
  EXPECT_EQ(refused.exit_code, 2) << refused.describe();
  EXPECT_TRUE(contains_ci(refused.out + refused.err, "incomplete")) << refused.describe();
  const CmdResult rep = st.ctl({"reprocess", std::to_string(k.run_id), "--partial", "--wait"}, 180s);
  std::fprintf(stderr, "[e2e] reprocess --partial of a run killed while running: exit %d\n%s%s", rep.exit_code,
               rep.out.c_str(), rep.err.c_str());
  EXPECT_EQ(rep.exit_code, 1) << rep.describe();
  const json newest = newest_run(st, "SIM-0300");
  ASSERT_TRUE(newest.is_object());
  EXPECT_NE(newest.value("run_id", -1LL), k.run_id);
  EXPECT_EQ(newest["reprocessed_from"], json(k.run_id)) << newest.dump(2);
  const std::string state = newest.value("state", "");
  EXPECT_TRUE(state == "review" || state == "failed") << newest.dump(2);
  EXPECT_FALSE(newest.value("failure_reason", "").empty()) << newest.dump(2);
  // Issue #19 item 2: the verdict follows the state (it showed the cross-check's PASS).
  EXPECT_EQ(newest.value("verdict", ""), state == "review" ? "REVIEW" : "FAILED") << newest.dump(2);
  EXPECT_EQ(rep.out.find("verdict PASS"), std::string::npos) << rep.describe();
  const CmdResult params = st.ctl({"params", "SIM-0300"});
  EXPECT_NE(params.exit_code, 0) << "a partial archive became active:\n" << params.describe();
  // The interrupted run stays interrupted (terminal states are final).
  EXPECT_EQ(show_run(st, k.run_id)["run"].value("state", ""), "interrupted");
}

TEST(StationRecovery, KillNineWhileCalibratingThenRestartAndReprocessPasses) {
  Station st;
  ASSERT_TRUE(st.start(SimOptions{200.0, 22, {}}));
  const Killed k = start_and_kill(st, "SIM-0301", [](const json& r) {
    return r.value("state", "") == "calibrating" || r.value("phase", "") == "calibrating";
  });
  ASSERT_GT(k.run_id, 0);
  ASSERT_FALSE(k.last_status.is_null()) << "never saw the run calibrating:\n" << st.daemon_log();
  ASSERT_TRUE(st.start_daemon()) << st.daemon_log();
  // The capture had finished (run.toml rewritten with [capture] complete = true) before calibrating.
  const json run = check_interrupted(st, k.run_id, /*capture_complete=*/true);
  ASSERT_TRUE(run.is_object());
  EXPECT_TRUE(contains_ci(run.value("failure_reason", ""), "calibrating")) << run.dump(2);

  // The archive was complete when the daemon died: reprocessing it must PASS, and with the same
  // digest the archive is the one the run wrote (reprocess reads it, never rewrites it).
  const std::string digest_before = run.value("archive_sha256", "");
  const CmdResult rep = st.ctl({"reprocess", std::to_string(k.run_id), "--wait"}, 180s);
  EXPECT_EQ(rep.exit_code, 0) << rep.describe() << "\n" << st.daemon_log();
  const json newest = newest_run(st, "SIM-0301");
  ASSERT_TRUE(newest.is_object());
  EXPECT_EQ(newest["reprocessed_from"], json(k.run_id)) << newest.dump(2);
  EXPECT_EQ(newest.value("state", ""), "done") << newest.dump(2);
  EXPECT_EQ(newest["verdict"], json("PASS")) << newest.dump(2);
  EXPECT_EQ(show_run(st, k.run_id)["run"].value("archive_sha256", ""), digest_before);
  // And the reprocessed result is the serial's active calibration.
  const CmdResult params = st.ctl({"--json", "params", "SIM-0301"});
  EXPECT_EQ(params.exit_code, 0) << params.describe();
}

}  // namespace
}  // namespace imucal::e2e
