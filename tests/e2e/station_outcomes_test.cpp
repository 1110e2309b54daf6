// Whose a run's end was (issue #50 item 1), with the daemon and the simulator as processes:
//   * the table down (the simulator gone, Modbus unreachable): the run is the station's fault —
//     verdict STATION-FAULT, the unit's yield unchanged, the station's fault count up;
//   * an operator's `run abort` mid-run: verdict ABORTED, not the unit's FAILED.
#include "tests/e2e/station_harness.hpp"

namespace imucal::e2e {
namespace {

bool terminal(const std::string& s) {
  return s == "done" || s == "review" || s == "failed" || s == "aborted" || s == "interrupted";
}

/// The newest run of `serial` once it has ended (null on timeout).
json wait_ended(const Station& st, const std::string& serial, std::chrono::milliseconds timeout) {
  json rec;
  const bool ok = wait_until(
      [&] {
        rec = newest_run(st, serial);
        return rec.is_object() && terminal(rec.value("state", ""));
      },
      timeout, 200ms);
  return ok ? rec : json();
}

/// `stationctl --db FILE --json stations`: this station's counts (null if it lists none).
json station_counts(const Station& st) {
  const CmdResult r = st.ctl({"--db", st.db_path(), "--json", "stations"});
  EXPECT_EQ(r.exit_code, 0) << r.describe();
  const json j = json::parse(r.out, nullptr, false);
  if (!j.is_object() || !j.contains("stations") || j["stations"].size() != 1) {
    ADD_FAILURE() << "one station expected: " << r.describe();
    return json();
  }
  return j["stations"][0];
}

TEST(StationOutcomes, TheTableDownIsAStationFaultAndLeavesTheUnitsYieldAlone) {
  Station st;
  ASSERT_TRUE(st.start_sim());
  // Give up on an unreachable table after 2 s instead of the default 10 s.
  std::string text = st.config_text();
  const auto at = text.find("[turntable]\n");
  ASSERT_NE(at, std::string::npos);
  text.insert(at + 12, "reconnect_give_up_ms = 2000\n");
  st.write_config(text);
  ASSERT_TRUE(st.start_daemon());

  // A run the unit decides: PASS (or REVIEW, with a reason) on a working station.
  const CmdResult first =
      st.ctl({"run", "start", "--serial", "SIM-0950", "--sequence", "short", "--wait"}, 180s);
  const json decided = newest_run(st, "SIM-0950");
  ASSERT_TRUE(decided.is_object()) << first.describe();
  const std::string own_verdict = decided.value("verdict", "");
  ASSERT_TRUE(own_verdict == "PASS" || own_verdict == "REVIEW") << decided.dump(2);
  const json before = station_counts(st);
  EXPECT_EQ(before.value("unit_outcomes", -1), 1) << before.dump(2);
  EXPECT_EQ(before.value("station_faults", -1), 0) << before.dump(2);

  // The table goes away: the simulator (its Modbus server) stops; the unit never moves.
  st.sim().terminate(5s);
  const CmdResult down =
      st.ctl({"run", "start", "--serial", "SIM-0950", "--sequence", "short", "--wait"}, 120s);
  EXPECT_EQ(down.exit_code, 1) << "the run did not pass: " << down.describe();
  const json rec = wait_ended(st, "SIM-0950", 60s);
  ASSERT_TRUE(rec.is_object()) << st.daemon_log();
  EXPECT_NE(rec.value("run_id", 0LL), decided.value("run_id", 0LL));
  EXPECT_EQ(rec.value("state", ""), "aborted") << rec.dump(2);
  EXPECT_EQ(rec.value("verdict", ""), "STATION-FAULT") << rec.dump(2);
  EXPECT_EQ(rec.value("outcome_of", ""), "station") << rec.dump(2);
  EXPECT_TRUE(contains_ci(rec.value("failure_reason", ""), "cannot connect")) << rec.dump(2);
  EXPECT_TRUE(contains_ci(down.out + down.err, "STATION-FAULT")) << down.describe();

  // The unit's yield counts its own outcome alone; the station's faults are counted apart.
  const json after = station_counts(st);
  EXPECT_EQ(after.value("unit_outcomes", -1), 1) << after.dump(2);
  EXPECT_EQ(after.value("failed", -1), 0) << after.dump(2);
  EXPECT_EQ(after.value("pass", -1), before.value("pass", -2)) << after.dump(2);
  EXPECT_EQ(after.value("station_faults", -1), 1) << after.dump(2);
  EXPECT_EQ(after.value("runs", -1), 2) << after.dump(2);
  const CmdResult history = st.ctl({"history", "SIM-0950"});
  ASSERT_EQ(history.exit_code, 0) << history.describe();
  const std::string yield_line = std::string("Yield: ") + (own_verdict == "PASS" ? "1" : "0") +
                                 " PASS of 1 run(s) the unit decided";
  EXPECT_NE(history.out.find(yield_line), std::string::npos) << history.out;
  EXPECT_NE(history.out.find("1 station fault(s)"), std::string::npos) << history.out;
  // The export says whose each end was.
  const CmdResult exported = st.ctl({"export", "--serial", "SIM-0950", "--format", "json"});
  ASSERT_EQ(exported.exit_code, 0) << exported.describe();
  const json rows = json::parse(exported.out, nullptr, false);
  ASSERT_TRUE(rows.is_array()) << exported.describe();
  std::map<long long, std::string> owner;
  for (const json& row : rows) owner[row.value("run_id", 0LL)] = row.value("outcome_of", "");
  EXPECT_EQ(owner[rec.value("run_id", 0LL)], "station") << exported.out.substr(0, 2000);
  EXPECT_EQ(owner[decided.value("run_id", 0LL)], "unit") << exported.out.substr(0, 2000);
}

TEST(StationOutcomes, AnOperatorsAbortIsAnAbortNotTheUnitsFailure) {
  Station st;
  ASSERT_TRUE(st.start(SimOptions{20.0, 7, {}}));  // slow enough to be mid-run
  const CmdResult start = st.ctl({"run", "start", "--serial", "SIM-0951", "--sequence", "short"});
  ASSERT_EQ(start.exit_code, 0) << start.describe();
  const json running =
      st.wait_live_run([](const json& r) { return r.value("state", "") == "running"; }, 60s);
  ASSERT_FALSE(running.is_null()) << st.daemon_log();
  const CmdResult abort = st.ctl({"run", "abort", "--reason", "unit loose in fixture"});
  ASSERT_EQ(abort.exit_code, 0) << abort.describe();
  const json rec = wait_ended(st, "SIM-0951", 30s);
  ASSERT_TRUE(rec.is_object()) << st.daemon_log();
  EXPECT_EQ(rec.value("state", ""), "aborted") << rec.dump(2);
  EXPECT_EQ(rec.value("verdict", ""), "ABORTED") << rec.dump(2);
  EXPECT_EQ(rec.value("outcome_of", ""), "operator") << rec.dump(2);
  EXPECT_EQ(rec.value("failure_reason", "").rfind("unit loose in fixture", 0), 0u) << rec.dump(2);
  const CmdResult shown = st.ctl({"show", std::to_string(rec.value("run_id", 0LL))});
  EXPECT_NE(shown.out.find("aborted by an operator"), std::string::npos) << shown.describe();
  const json counts = station_counts(st);
  EXPECT_EQ(counts.value("aborted", -1), 1) << counts.dump(2);
  EXPECT_EQ(counts.value("failed", -1), 0) << counts.dump(2);
  EXPECT_EQ(counts.value("unit_outcomes", -1), 0) << counts.dump(2);
}

}  // namespace
}  // namespace imucal::e2e
