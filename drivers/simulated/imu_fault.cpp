#include "drivers/simulated/imu_fault.hpp"

#include <algorithm>
#include <stdexcept>

#include "calib/core/conventions.hpp"
#include "drivers/imu/imu_protocol.hpp"

namespace imucal::drivers::simulated {

namespace {

const char* const kChannels[6] = {"gyro-x", "gyro-y", "gyro-z", "accel-x", "accel-y", "accel-z"};

int parse_channel(const std::string& name, const std::string& text) {
  for (int c = 0; c < 6; ++c)
    if (name == kChannels[c]) return c;
  throw std::invalid_argument("--imu-fault " + text + ": unknown channel '" + name +
                              "' (gyro-x, gyro-y, gyro-z, accel-x, accel-y, accel-z)");
}

double& channel(calib::core::ImuIncrement& inc, int c) {
  return c < 3 ? inc.dtheta_rad(c) : inc.dv_mps(c - 3);
}

constexpr size_t kReplaySamples = 500;  ///< not-on-table: the first 5 s at 100 Hz

}  // namespace

ImuFault parse_imu_fault(const std::string& text) {
  const auto colon = text.find(':');
  const std::string kind = text.substr(0, colon);
  const std::string arg = colon == std::string::npos ? "" : text.substr(colon + 1);
  ImuFault f;
  if (kind == "stuck" || kind == "flip") {
    f.kind = kind == "stuck" ? ImuFault::Kind::kStuck : ImuFault::Kind::kFlip;
    f.channel = parse_channel(arg, text);
  } else if (kind == "swap" && arg == "gyro-xy") {
    f.kind = ImuFault::Kind::kSwapGyroXy;
  } else if (kind == "not-on-table" && arg.empty()) {
    f.kind = ImuFault::Kind::kNotOnTable;
  } else if (kind == "fixture-rot90" && arg.empty()) {
    f.kind = ImuFault::Kind::kFixtureRot90;
  } else if (kind == "saturate") {
    f.kind = ImuFault::Kind::kSaturate;
    try {
      f.limit_dps = std::stod(arg);
    } catch (const std::exception&) {
      f.limit_dps = 0.0;
    }
    if (!(f.limit_dps > 0.0))
      throw std::invalid_argument("--imu-fault " + text + ": saturate needs a positive DPS");
  } else {
    throw std::invalid_argument("--imu-fault " + text +
                                ": expected stuck:CH, swap:gyro-xy, flip:CH, not-on-table, "
                                "fixture-rot90 or saturate:DPS");
  }
  return f;
}

uint16_t ImuFaultInjector::apply(calib::core::ImuIncrement& inc) {
  switch (fault_.kind) {
    case ImuFault::Kind::kNone:
      return 0;
    case ImuFault::Kind::kStuck:
      channel(inc, fault_.channel) = 0.0;
      return 0;
    case ImuFault::Kind::kFlip:
      channel(inc, fault_.channel) = -channel(inc, fault_.channel);
      return 0;
    case ImuFault::Kind::kSwapGyroXy:
      std::swap(inc.dtheta_rad(0), inc.dtheta_rad(1));
      return 0;
    case ImuFault::Kind::kFixtureRot90:
      inc.dtheta_rad = Eigen::Vector3d(inc.dtheta_rad(1), -inc.dtheta_rad(0), inc.dtheta_rad(2));
      inc.dv_mps = Eigen::Vector3d(inc.dv_mps(1), -inc.dv_mps(0), inc.dv_mps(2));
      return 0;
    case ImuFault::Kind::kSaturate: {
      const double lim = fault_.limit_dps * kDegToRad * inc.dt_s;
      const bool clipped = inc.dtheta_rad.cwiseAbs().maxCoeff() > lim;
      inc.dtheta_rad = inc.dtheta_rad.cwiseMax(-lim).cwiseMin(lim);
      return clipped ? drivers::imu::status::kGyroSaturated : 0;
    }
    case ImuFault::Kind::kNotOnTable: {
      if (replay_.size() < kReplaySamples) {
        replay_.push_back(inc);
      } else {
        const calib::core::ImuIncrement& still = replay_[n_ % kReplaySamples];
        inc.dtheta_rad = still.dtheta_rad;
        inc.dv_mps = still.dv_mps;
      }
      ++n_;
      return 0;
    }
  }
  return 0;
}

}  // namespace imucal::drivers::simulated
