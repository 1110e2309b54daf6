// End to end (issue #19 item 10): the live line's time left, as `run status` reports it while a
// `short` run plays on the 200× simulator. It used to start at the plan's real-time length
// ("8 min 44 s"), jump to "2 s" and read "30 s left" at the last step.
#include "tests/e2e/station_harness.hpp"

namespace imucal::e2e {
namespace {

TEST(StationTimeLeft, IsWallTimeAtTheSimulatorsSpeedNeverGrowsAndIsZeroOnlyAtTheEnd) {
  Station st;
  ASSERT_TRUE(st.start());
  const CmdResult start = st.ctl(
      {"run", "start", "--serial", "SIM-TL", "--sequence", "short", "--operator", "e2e"}, 30s);
  ASSERT_EQ(start.exit_code, 0) << start.describe();
  struct Poll {
    std::string state;
    int step = 0, steps = 0;
    std::optional<double> left_s;
  };
  std::vector<Poll> polls;
  const auto deadline = Clock::now() + 120s;
  while (Clock::now() < deadline) {
    const CmdResult s = st.ctl({"--json", "run", "status"}, 10s);
    ASSERT_EQ(s.exit_code, 0) << s.describe();
    const json j = s.json_out();
    if (!j.contains("run") || !j["run"].is_object()) break;  // ended
    const json& r = j["run"];
    const std::string state = r.value("state", "");
    if (state != "preparing" && state != "running") break;  // captured: calibrating
    Poll p{state, r["step"].is_number() ? r["step"].get<int>() : 0,
           r["steps"].is_number() ? r["steps"].get<int>() : 0, std::nullopt};
    if (r["time_left_s"].is_number()) p.left_s = r["time_left_s"].get<double>();
    polls.push_back(p);
  }
  ASSERT_GE(polls.size(), 5u) << "too few polls while the run captured";
  std::optional<double> first, prev;
  int estimates = 0;
  for (const Poll& p : polls) {
    if (!p.left_s) continue;
    ++estimates;
    if (!first) first = p.left_s;
    if (prev) {
      EXPECT_LE(*p.left_s, *prev) << "time left grew at step " << p.step;
    }
    // 0 once the last rest is captured (the run still reads "running" while its archive closes).
    if (p.step < p.steps) {
      EXPECT_GT(*p.left_s, 0.0) << "0 s left while step " << p.step << " of " << p.steps;
    }
    prev = p.left_s;
  }
  ASSERT_GE(estimates, 3) << "no time left shown while the run captured";
  // `short` is about 9 min of table time: at 200× its whole run is seconds of wall time.
  EXPECT_LT(*first, 30.0) << "the first estimate is table time, not wall time at 200×";
}

}  // namespace
}  // namespace imucal::e2e
