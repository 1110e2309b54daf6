#pragma once
// Physical faults of the simulated IMU for stationsim's `--imu-fault` (issue #10 item 3): a unit
// that is broken or wrongly mounted, so that the station's handling of it can be tested end to end.
//   stuck:CH        channel CH (gyro-x .. accel-z) reads 0 (a dead or stuck axis)
//   swap:gyro-xy    gyro x and y swapped (a wiring or configuration fault)
//   flip:CH         channel CH sign-flipped
//   not-on-table    the unit does not move with the table: it replays its first 5 s for ever
//   fixture-rot90   the unit is mounted turned 90° about its z axis (x reads y, y reads -x)
//   saturate:DPS    the gyros clip at ±DPS deg/s, and say so in their status (as real ones do)
#include <cstdint>
#include <string>
#include <vector>

#include "calib/core/imu_increment.hpp"

namespace imucal::drivers::simulated {

struct ImuFault {
  enum class Kind { kNone, kStuck, kSwapGyroXy, kFlip, kNotOnTable, kFixtureRot90, kSaturate };
  Kind kind = Kind::kNone;
  int channel = 0;         ///< 0..2 gyro x..z, 3..5 accel x..z (stuck, flip)
  double limit_dps = 0.0;  ///< saturate
};

/// Parses the `--imu-fault` text above; std::invalid_argument naming the problem.
ImuFault parse_imu_fault(const std::string& text);

/// Applies the fault to the unit's increments as they leave the sensor, in order.
class ImuFaultInjector {
 public:
  explicit ImuFaultInjector(ImuFault fault) : fault_(fault) {}
  /// Returns the status flags the sensor itself would raise (a clipped gyro reports saturation,
  /// drivers/imu/PROTOCOL.md), 0 otherwise.
  uint16_t apply(calib::core::ImuIncrement& inc);

 private:
  ImuFault fault_;
  std::vector<calib::core::ImuIncrement> replay_;
  size_t n_ = 0;
};

}  // namespace imucal::drivers::simulated
