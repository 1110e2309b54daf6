// Aborts and daemon stops as an operator meets them (issue #10):
//   * an abort while the table link is down (connecting, retrying) takes effect at once and the
//     run keeps the operator's reason, not the link error;
//   * SIGTERM to the daemon while `stationctl run start --wait` follows a run: the client reports
//     the run aborted (exit 1), not "daemon unreachable" (exit 4).
#include "tests/e2e/station_harness.hpp"

namespace imucal::e2e {
namespace {

TEST(StationAbort, AbortWhileTheTableLinkIsDownIsImmediateAndKeepsTheReason) {
  Station st;
  // No simulator: the turntable endpoint refuses connections, the client backs off and retries.
  std::string text = st.config_text();
  const auto at = text.find("[turntable]\n");
  ASSERT_NE(at, std::string::npos);
  text.insert(at + 12, "reconnect_give_up_ms = 60000\n");
  st.write_config(text);
  ASSERT_TRUE(st.start_daemon(60s));
  const CmdResult start = st.ctl({"run", "start", "--serial", "SIM-0800", "--sequence", "short"});
  ASSERT_EQ(start.exit_code, 0) << start.describe();
  std::this_thread::sleep_for(1500ms);  // several connection attempts, well inside the backoff
  const auto t0 = std::chrono::steady_clock::now();
  const CmdResult abort = st.ctl({"run", "abort", "--reason", "wrong unit mounted"});
  ASSERT_EQ(abort.exit_code, 0) << abort.describe();
  json rec;
  ASSERT_TRUE(wait_until(
      [&] {
        rec = newest_run(st, "SIM-0800");
        return rec.is_object() && rec.value("state", "") == "aborted";
      },
      20s, 50ms))
      << rec.dump(2) << "\n"
      << st.daemon_log();
  const double took_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_LT(took_s, 3.0) << "the abort waited for the connection backoff";
  EXPECT_EQ(rec.value("failure_reason", "").rfind("wrong unit mounted", 0), 0u) << rec.dump(2);
}

TEST(StationAbort, SigtermWhileFollowingARunReportsItAborted) {
  Station st;
  ASSERT_TRUE(st.start(SimOptions{20.0, 5, {}}));  // slow enough to be mid-run
  SpawnOptions so;
  so.stdout_path = st.dir() / "wait.out";
  so.stderr_path = st.dir() / "wait.err";
  Process follower({bin("stationctl"), "--config", st.config_path(), "run", "start", "--serial",
                    "SIM-0801", "--sequence", "short", "--wait"},
                   so);
  const json running =
      st.wait_live_run([](const json& r) { return r.value("state", "") == "running"; }, 60s);
  ASSERT_FALSE(running.is_null()) << st.daemon_log();
  st.daemon().signal(SIGTERM);
  const auto code = follower.wait_for(30s);
  ASSERT_TRUE(code.has_value()) << "stationctl --wait still running after the daemon stopped";
  const std::string out = read_text(so.stdout_path), err = read_text(so.stderr_path);
  ASSERT_TRUE(WIFEXITED(*code)) << *code;
  EXPECT_EQ(WEXITSTATUS(*code), 1) << out << err;
  EXPECT_TRUE(contains_ci(out, "aborted")) << out << err;
  EXPECT_TRUE(contains_ci(out, "SIGTERM")) << out << err;
}

}  // namespace
}  // namespace imucal::e2e
