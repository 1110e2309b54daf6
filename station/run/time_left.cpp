#include "station/run/time_left.hpp"

#include <algorithm>

namespace imucal::station::run {

std::optional<double> TimeLeftEstimator::update(double table_left_s, double table_done_s,
                                                double wall_s) {
  if (table_left_s <= 0.0) return last_s_ = 0.0;
  if (table_done_s < kMinTableS || wall_s < kMinWallS) return last_s_;
  // The average speed since the stream began: steadier than a window of recent samples, which
  // swings with a rest's quiet and a move's burst and once made the last rest read "30 s".
  const double speed = table_done_s / wall_s;
  double left_s = std::max(table_left_s / speed, kFloorS);
  if (last_s_) left_s = std::min(left_s, std::max(*last_s_, kFloorS));
  return last_s_ = left_s;
}

}  // namespace imucal::station::run
