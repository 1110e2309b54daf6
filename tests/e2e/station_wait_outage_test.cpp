// The waiting client across a daemon's death (issue #50 item 2): `stationctl run start --wait`
// follows a run, stationd is SIGKILLed. The client must say so in one line within 5 s (it printed
// "note: cannot connect … reading the database read-only instead" four times a second), wait
// quietly, and when the daemon is back exit with the documented "interrupted" code (5) and the
// run's real state (it exited 4, "stationd closed the connection"). While the daemon is down,
// `history` marks the run it still holds as running ("running (daemon not answering)").
#include "tests/e2e/station_harness.hpp"

namespace imucal::e2e {
namespace {

/// How many times `needle` occurs in `hay`.
std::size_t occurrences(const std::string& hay, const std::string& needle) {
  std::size_t n = 0;
  for (auto at = hay.find(needle); at != std::string::npos; at = hay.find(needle, at + 1)) ++n;
  return n;
}

/// The waiting client's stderr so far.
std::string client_err(const Station& st) { return read_text(st.path("wait.err")); }

TEST(StationWaitOutage, KilledDaemonIsSaidOnceHistoryMarksTheRunAndTheReturnGivesInterrupted) {
  Station st;
  ASSERT_TRUE(st.start(SimOptions{100.0, 51, {}}));
  SpawnOptions so;
  so.stdout_path = st.path("wait.out");
  so.stderr_path = st.path("wait.err");
  Process client({st.program("stationctl"), "--config", st.config_path(), "run", "start",
                  "--serial", "SIM-0500", "--sequence", "short", "--wait"},
                 so);
  const json live = st.wait_live_run(
      [](const json& r) { return r.value("state", "") == "running" && r.value("step", 0) >= 2; },
      120s);
  ASSERT_FALSE(live.is_null()) << "the run never reached step 2:\n" << st.daemon_log();
  const long long run_id = run_id_of(live);
  ASSERT_GT(run_id, 0) << live.dump();

  st.daemon().kill9();
  const auto killed_at = Clock::now();
  ASSERT_TRUE(wait_until([&] { return contains_ci(client_err(st), "stopped answering"); }, 5s))
      << "the client did not say within 5 s that the daemon stopped answering:\n"
      << client_err(st);
  std::fprintf(stderr, "[e2e] the client said so after %.2f s\n",
               std::chrono::duration<double>(Clock::now() - killed_at).count());

  // History during the outage: read from the database, the run marked.
  const CmdResult history = st.ctl({"history", "SIM-0500"});
  EXPECT_EQ(history.exit_code, 0) << history.describe();
  EXPECT_TRUE(contains_ci(history.out, "running (daemon not answering)")) << history.describe();
  const json runs = history_runs(st, "SIM-0500");
  ASSERT_EQ(runs.size(), 1u) << runs.dump(2);
  EXPECT_EQ(runs[0].value("state", ""), "running") << runs.dump(2);
  EXPECT_EQ(runs[0].value("state_note", ""), "daemon not answering") << runs.dump(2);

  // Down for a while (the outage is what is tested: no condition ends it early): the client keeps
  // waiting, and says nothing more than its one line.
  std::this_thread::sleep_for(4s);
  EXPECT_TRUE(client.running()) << "the client gave up:\n" << client_err(st);
  const std::string during = client_err(st);
  EXPECT_EQ(occurrences(lower(during), "stopped answering"), 1u) << during;
  EXPECT_EQ(occurrences(during, "reading the database"), 0u) << during;

  ASSERT_TRUE(st.start_daemon()) << st.daemon_log();
  const auto code = client.exit_code(20s);
  ASSERT_TRUE(code.has_value()) << "the client did not see the daemon return:\n" << client_err(st);
  const std::string out = read_text(st.path("wait.out"));
  EXPECT_EQ(*code, 5) << "stdout:\n" << out << "\nstderr:\n" << client_err(st);
  EXPECT_TRUE(contains_ci(out, "interrupted")) << out;
  EXPECT_EQ(show_run(st, run_id)["run"].value("state", ""), "interrupted");
  // With the daemon back, history no longer carries the note.
  EXPECT_FALSE(newest_run(st, "SIM-0500").contains("state_note"));
}

}  // namespace
}  // namespace imucal::e2e
