// Faults (issue #3, "What it must show"), injected by stationsim's knobs into real processes:
//   * 1 % CAN frame loss and 0.1 % corrupt frames: counted, reported by `show`, and the run still
//     passes or goes to review with a reason;
//   * a dropped Modbus connection mid-run: recovered, or the run aborts with the table stopped;
//   * a table fault mid-move: the run aborts cleanly, the reason names the fault;
//   * a second `run start` while a run is active: refused (exit 3) with a clear message.
#include <cmath>

#include "tests/e2e/station_harness.hpp"

namespace imucal::e2e {
namespace {

bool terminal(const std::string& s) {
  return s == "done" || s == "review" || s == "failed" || s == "aborted" || s == "interrupted";
}

/// Waits until the newest run of `serial` is terminal; returns it (null on timeout).
json wait_terminal(const Station& st, const std::string& serial, std::chrono::milliseconds timeout) {
  json rec;
  const bool ok = wait_until(
      [&] {
        const CmdResult r = st.ctl({"--json", "history", serial});
        if (r.exit_code != 0) return false;
        const json j = json::parse(r.out, nullptr, false);
        if (!j.is_object() || !j.contains("runs") || j["runs"].empty()) return false;
        rec = j["runs"][0];
        return terminal(rec.value("state", ""));
      },
      timeout, 200ms);
  return ok ? rec : json();
}

/// The table stands still: mbpoll (not our client) sees no motion bit, zero rates and the same
/// angles twice, 0.3 s (30 sim s at speed 100) apart.
void expect_table_stopped(const Station& st) {
  const TableReading a = read_table(st);
  std::this_thread::sleep_for(300ms);
  const TableReading b = read_table(st);
  ASSERT_TRUE(a.ok && b.ok) << a.raw << "\n" << b.raw;
  EXPECT_FALSE(b.moving()) << b.raw;
  EXPECT_EQ(b.rate_outer_dps, 0.0) << b.raw;
  EXPECT_EQ(b.rate_inner_dps, 0.0) << b.raw;
  EXPECT_EQ(a.outer_deg, b.outer_deg) << a.raw << "\n" << b.raw;
  EXPECT_EQ(a.inner_deg, b.inner_deg) << a.raw << "\n" << b.raw;
}

TEST(StationFaults, CanLossAndCorruptionAreCountedAndTheRunPassesOrGoesToReviewWithAReason) {
  Station st;
  ASSERT_TRUE(st.start(SimOptions{200.0, 11, {"--can-loss", "0.01", "--can-corrupt", "0.001"}}));
  const CmdResult run = st.ctl({"run", "start", "--serial", "SIM-0200", "--sequence", "short", "--wait"}, 180s);
  ASSERT_TRUE(run.exit_code == 0 || run.exit_code == 1) << run.describe() << "\n" << st.daemon_log();
  const json rec = newest_run(st, "SIM-0200");
  ASSERT_TRUE(rec.is_object());
  const std::string state = rec.value("state", "");
  if (run.exit_code == 0) {
    EXPECT_EQ(state, "done");
    EXPECT_EQ(rec["verdict"], json("PASS"));
  } else {
    EXPECT_EQ(state, "review") << "1 % loss must not fail the run:\n" << rec.dump(2);
    EXPECT_FALSE(rec.value("failure_reason", "").empty()) << "review without a reason:\n" << rec.dump(2);
  }
  std::fprintf(stderr, "[e2e] CAN loss run: state %s, exit %d\n", state.c_str(), run.exit_code);

  const json shown = show_run(st, rec.value("run_id", -1LL));
  const json& c = shown["run"]["capture"];
  ASSERT_TRUE(c.is_object()) << shown.dump(2);
  std::fprintf(stderr, "[e2e] capture counters: %s\n", c.dump().c_str());
  // Lost frames make samples go missing (incomplete, or counter gaps); they are filled and counted.
  EXPECT_GT(num(c, "samples_lost") + num(c, "samples_incomplete"), 0.0) << c.dump(2);
  EXPECT_GT(num(c, "samples_filled"), 0.0) << c.dump(2);
  // Corrupt frames fail the sample CRC (or, if the counter byte was hit, look like foreign/malformed).
  EXPECT_GT(num(c, "samples_corrupt") + num(c, "frames_malformed") + num(c, "frames_foreign"), 0.0) << c.dump(2);
  EXPECT_GT(num(c, "samples_decoded"), 10000.0) << c.dump(2);
  // Text output (for people) reports the losses too.
  const CmdResult text = st.ctl({"show", std::to_string(rec.value("run_id", -1LL))});
  ASSERT_EQ(text.exit_code, 0) << text.describe();
  EXPECT_TRUE(contains_ci(text.out, "lost")) << text.describe();

  // Cross-check against the simulator's own count of what it dropped and corrupted.
  ASSERT_EQ(st.daemon().terminate(15s), std::optional<int>(0));
  ASSERT_EQ(st.sim().terminate(10s), std::optional<int>(0)) << read_text(st.path("sim.err"));
  const json sim = st.sim_stats();
  ASSERT_TRUE(sim.is_object()) << read_text(st.sim_stats_path());
  EXPECT_GT(num(sim, "frames_lost"), 0.0) << sim.dump(2);
  EXPECT_GT(num(sim, "frames_corrupted"), 0.0) << sim.dump(2);
  // Every incomplete sample needs a lost or damaged frame (the sim also streamed outside the run).
  EXPECT_LE(num(c, "samples_incomplete"), num(sim, "frames_lost") + num(sim, "frames_corrupted"))
      << sim.dump(2) << c.dump(2);
}

TEST(StationFaults, DroppedModbusConnectionMidRunIsRecoveredOrAbortsWithTheTableStopped) {
  Station st;
  const double speed = 100.0;
  const double drop_at_s = 300.0;  // sim s: the short sequence runs from ~ sim 100 s to ~ 700 s
  const auto sim_started = Clock::now();
  ASSERT_TRUE(st.start(SimOptions{speed, 12, {"--modbus-drop-at", "300"}}));
  const CmdResult start = st.ctl({"--json", "run", "start", "--serial", "SIM-0201", "--sequence", "short"});
  ASSERT_EQ(start.exit_code, 0) << start.describe();
  const json running = st.wait_live_run([](const json& r) { return r.value("state", "") == "running"; }, 30s);
  ASSERT_FALSE(running.is_null()) << st.daemon_log();
  const double sim_at_running = std::chrono::duration<double>(Clock::now() - sim_started).count() * speed;
  ASSERT_LT(sim_at_running, drop_at_s - 20.0)
      << "set-up too slow: the run began at sim ~" << sim_at_running << " s, after the drop";

  const json rec = wait_terminal(st, "SIM-0201", 120s);
  ASSERT_TRUE(rec.is_object()) << st.daemon_log();
  const std::string state = rec.value("state", "");
  std::fprintf(stderr, "[e2e] Modbus drop: run %s, reason \"%s\"\n", state.c_str(),
               rec.value("failure_reason", "").c_str());
  if (state == "aborted") {
    EXPECT_FALSE(rec.value("failure_reason", "").empty());
    expect_table_stopped(st);
  } else {
    EXPECT_TRUE(state == "done" || state == "review") << "neither recovered nor aborted:\n" << rec.dump(2);
  }
  // The drop did happen while the run was live.
  ASSERT_EQ(st.daemon().terminate(15s), std::optional<int>(0));
  ASSERT_EQ(st.sim().terminate(10s), std::optional<int>(0));
  const json sim = st.sim_stats();
  EXPECT_GE(num(sim, "modbus_drops"), 1.0) << sim.dump(2);
  const double ended_ms = num(rec, "ended_at_ms"), started_ms = num(rec, "started_at_ms");
  EXPECT_GT((ended_ms - started_ms) / 1000.0 * speed + sim_at_running, drop_at_s)
      << "the run ended before the drop (sim time), the scenario was not exercised";
}

/// Starts a run at speed 100 whose sim time passes `event_at_s` while the run is running (asserted);
/// returns the terminal run record and the sim time at which the run was seen running.
struct MidRun {
  json rec;
  double sim_at_running = 0;
};
MidRun run_through_event(Station& st, const std::string& serial, double speed, double event_at_s) {
  MidRun m;
  const CmdResult start = st.ctl({"--json", "run", "start", "--serial", serial, "--sequence", "short"});
  EXPECT_EQ(start.exit_code, 0) << start.describe();
  const json running = st.wait_live_run([](const json& r) { return r.value("state", "") == "running"; }, 30s);
  EXPECT_FALSE(running.is_null()) << st.daemon_log();
  m.sim_at_running = st.sim_seconds(speed);
  EXPECT_LT(m.sim_at_running, event_at_s - 20.0)
      << "set-up too slow: the run began at sim ~" << m.sim_at_running << " s, after the event";
  m.rec = wait_terminal(st, serial, 120s);
  EXPECT_TRUE(m.rec.is_object()) << st.daemon_log();
  return m;
}

TEST(StationFaults, ImuResetMidRunFailsTheRunNamingTheResetWithTheTableStopped) {
  Station st;
  ASSERT_TRUE(st.start(SimOptions{100.0, 15, {"--imu-reset-at", "300"}}));
  const MidRun m = run_through_event(st, "SIM-0205", 100.0, 300.0);
  ASSERT_TRUE(m.rec.is_object());
  std::fprintf(stderr, "[e2e] IMU reset: run %s, reason \"%s\"\n", m.rec.value("state", "").c_str(),
               m.rec.value("failure_reason", "").c_str());
  // A reset loses the unit's state mid-sequence: the data cannot be calibrated as one run.
  EXPECT_EQ(m.rec.value("state", ""), "failed") << m.rec.dump(2);
  EXPECT_TRUE(contains_ci(m.rec.value("failure_reason", ""), "reset")) << m.rec.dump(2);
  expect_table_stopped(st);
  EXPECT_GE(num(m.rec["capture"], "imu_resets"), 1.0) << m.rec.dump(2);
}

TEST(StationFaults, ModbusReplyDelaysMidRunAreRecoveredOrAbortWithTheTableStopped) {
  Station st;
  // From sim 300 s, 3 replies held back 600 ms each (the daemon's response timeout is 250 ms).
  ASSERT_TRUE(st.start(SimOptions{100.0, 16, {"--modbus-delay-at", "300:600:3"}}));
  const MidRun m = run_through_event(st, "SIM-0206", 100.0, 300.0);
  ASSERT_TRUE(m.rec.is_object());
  const std::string state = m.rec.value("state", "");
  std::fprintf(stderr, "[e2e] Modbus delays: run %s, reason \"%s\"\n", state.c_str(),
               m.rec.value("failure_reason", "").c_str());
  if (state == "aborted") {
    EXPECT_FALSE(m.rec.value("failure_reason", "").empty());
    expect_table_stopped(st);
  } else {
    EXPECT_TRUE(state == "done" || state == "review") << "neither recovered nor aborted:\n" << m.rec.dump(2);
  }
}

TEST(StationFaults, TableFaultMidMoveAbortsTheRunCleanlyNamingTheFault) {
  Station st;
  ASSERT_TRUE(st.start(SimOptions{200.0, 13, {"--table-fault-move", "3:1.0:17"}}));
  const CmdResult run = st.ctl({"run", "start", "--serial", "SIM-0202", "--sequence", "short", "--wait"}, 120s);
  EXPECT_EQ(run.exit_code, 1) << run.describe();
  const json rec = newest_run(st, "SIM-0202");
  ASSERT_TRUE(rec.is_object());
  EXPECT_EQ(rec.value("state", ""), "aborted") << rec.dump(2);
  const std::string reason = rec.value("failure_reason", "");
  EXPECT_TRUE(contains_ci(reason, "fault")) << "reason: " << reason;
  EXPECT_NE(reason.find("17"), std::string::npos) << "the fault code is not named: " << reason;
  EXPECT_TRUE(contains_ci(run.out + run.err, "aborted")) << run.describe();
  // Stopped, and the archive of the aborted run is finished (run.toml with an end time).
  expect_table_stopped(st);
  const std::string archive_dir = rec.value("archive_path", "");
  ASSERT_TRUE(fs::exists(archive_dir + "/run.toml")) << rec.dump(2);
  EXPECT_TRUE(std::regex_search(read_text(archive_dir + "/run.toml"), std::regex(R"(end_time\s*=\s*"\d{4}-)")))
      << read_text(archive_dir + "/run.toml");
  // No calibration is stored for an aborted run, and the daemon takes the next run.
  const json shown = show_run(st, rec.value("run_id", -1LL));
  EXPECT_TRUE(shown["calibrations"].empty()) << shown.dump(2);
  const json status = st.request("run.status").value_or(json());
  EXPECT_EQ(status["result"].value("state", ""), "idle") << status.dump(2);
}

TEST(StationFaults, SecondRunStartWhileOneIsRunningIsRefusedWithAClearMessage) {
  Station st;
  ASSERT_TRUE(st.start(SimOptions{50.0, 14, {}}));  // slow enough that the first run stays active
  const CmdResult first = st.ctl({"--json", "run", "start", "--serial", "SIM-0203", "--sequence", "short"});
  ASSERT_EQ(first.exit_code, 0) << first.describe();
  const long long first_id = run_id_of(first.json_out());
  ASSERT_FALSE(st.wait_live_run([](const json& r) { return r.value("state", "") == "running"; }, 30s).is_null());

  const CmdResult second = st.ctl({"run", "start", "--serial", "SIM-0204", "--sequence", "short"});
  EXPECT_EQ(second.exit_code, 3) << second.describe();
  // Clear: it says that a run is active and which one (serial or run id).
  const std::string msg = second.out + second.err;
  EXPECT_TRUE(contains_ci(msg, "busy") || contains_ci(msg, "already") || contains_ci(msg, "is running") ||
              contains_ci(msg, "in progress") || contains_ci(msg, "active"))
      << "not a clear refusal:\n" << second.describe();
  EXPECT_TRUE(msg.find("SIM-0203") != std::string::npos || msg.find("run " + std::to_string(first_id)) != std::string::npos)
      << "the refusal does not name the active run:\n" << second.describe();
  std::fprintf(stderr, "[e2e] second run start: %s", second.err.c_str());
  // The protocol's code for it, through the socket.
  const auto raw = st.request("run.start", {{"serial", "SIM-0204"}, {"sequence", "short"}});
  ASSERT_TRUE(raw) << "no reply";
  EXPECT_EQ((*raw)["ok"], json(false)) << raw->dump();
  EXPECT_EQ((*raw)["error"].value("code", ""), "busy") << raw->dump();
  // Nothing stored for the refused serial, and the first run is unaffected.
  EXPECT_EQ(stored_run_count(st.db_path(), "SIM-0204"), 0);
  const json live = st.live_run();
  EXPECT_EQ(run_id_of(live), first_id) << live.dump(2);

  // Abort the first one: aborted, table stopped.
  const CmdResult abort = st.ctl({"run", "abort", "--reason", "e2e test abort"});
  EXPECT_EQ(abort.exit_code, 0) << abort.describe();
  const json rec = wait_terminal(st, "SIM-0203", 30s);
  ASSERT_TRUE(rec.is_object());
  EXPECT_EQ(rec.value("state", ""), "aborted");
  EXPECT_TRUE(contains_ci(rec.value("failure_reason", ""), "e2e test abort")) << rec.dump(2);
  expect_table_stopped(st);
}

}  // namespace
}  // namespace imucal::e2e
