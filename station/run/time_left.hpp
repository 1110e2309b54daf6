#pragma once
// The live line's "time left" (issue #19 item 10): wall time at the speed the IMU data really
// arrive (a simulator may run 400× real time, a real table 1×), never growing, and 0 only once the
// plan's last rest is captured. Before the speed is known there is no estimate (it printed the
// plan's real-time length, "8 min 44 s", on a 200× simulator, then jumped to "2 s").
#include <optional>

namespace imucal::station::run {

class TimeLeftEstimator {
 public:
  /// Data needed before the speed counts as measured: this much table time, this much wall time.
  static constexpr double kMinTableS = 1.0;
  static constexpr double kMinWallS = 0.05;
  /// While anything is left the estimate stays at least this (so "0 s" means done).
  static constexpr double kFloorS = 0.5;

  /// table_left_s: the plan's remaining table time; table_done_s: the IMU data's span captured
  /// since the stream began; wall_s: wall time since then. nullopt while the speed is unknown.
  std::optional<double> update(double table_left_s, double table_done_s, double wall_s);

 private:
  std::optional<double> last_s_;
};

}  // namespace imucal::station::run
