// Issue #19 item 10: the live line's time left on a 200× simulator started at the plan's real-time
// length ("8 min 44 s"), jumped to "2 s", and read "30 s left" at the last step. The estimator is
// fed what the controller sees: the plan's remaining table time, the table time captured and the
// wall time since the stream began.
#include "station/run/time_left.hpp"

#include <gtest/gtest.h>

#include <vector>

namespace imucal::station {
using namespace imucal::station::run;
namespace {

/// A run of `plan_s` table seconds played at `speed`×, with the data arriving in bursts (moves
/// stream, rests are quiet for a while on a loaded machine): the estimate at every poll.
std::vector<std::optional<double>> play(double plan_s, double speed, double poll_wall_s) {
  TimeLeftEstimator est;
  std::vector<std::optional<double>> out;
  double wall_s = 0.0, done_s = 0.0;
  for (int k = 0; done_s < plan_s; ++k) {
    wall_s += poll_wall_s;
    // Every fifth poll the data stall (a busy CPU), the next one catches up.
    const double arrived = (k % 5 == 3) ? 0.0 : (k % 5 == 4 ? 2.0 : 1.0) * poll_wall_s * speed;
    done_s = std::min(plan_s, done_s + arrived);
    out.push_back(est.update(plan_s - done_s, done_s, wall_s));
  }
  return out;
}

TEST(TimeLeft, IsWallTimeAtTheMeasuredSpeedNeverGrowsAndReachesZeroOnlyAtTheEnd) {
  const double plan_s = 524.0, speed = 200.0;  // factory-std-like 8 min 44 s at 200×
  const auto left = play(plan_s, speed, 0.02);
  ASSERT_GT(left.size(), 20u);
  // No estimate before a second of data: never the plan's real-time length.
  std::optional<double> first;
  for (const auto& l : left)
    if (l) {
      first = l;
      break;
    }
  ASSERT_TRUE(first.has_value());
  EXPECT_LT(*first, 2.0 * plan_s / speed) << "the first estimate is real time, not wall time";
  EXPECT_GT(*first, 0.5 * plan_s / speed);
  std::optional<double> prev;
  for (std::size_t i = 0; i < left.size(); ++i) {
    if (!left[i]) continue;
    if (prev) {
      EXPECT_LE(*left[i], *prev) << "poll " << i << " grew";
    }
    if (i + 1 < left.size()) {
      EXPECT_GE(*left[i], TimeLeftEstimator::kFloorS) << "poll " << i;
    }
    prev = left[i];
  }
  ASSERT_TRUE(left.back().has_value());
  EXPECT_EQ(*left.back(), 0.0) << "0 once the last rest is captured";
}

TEST(TimeLeft, ARealTableRunsAtItsOwnSpeed) {
  TimeLeftEstimator est;
  // 1× speed: after 60 s of a 600 s plan, 540 s left.
  EXPECT_FALSE(est.update(600.0, 0.5, 0.5).has_value());
  const auto l = est.update(540.0, 60.0, 60.0);
  ASSERT_TRUE(l.has_value());
  EXPECT_NEAR(*l, 540.0, 1e-9);
}

}  // namespace
}  // namespace imucal::station
