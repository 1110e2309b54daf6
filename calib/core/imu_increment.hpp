#pragma once
// One IMU sample: increments over [t_s - dt_s, t_s] (see conventions.hpp for their exact meaning).
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <vector>

namespace imucal::calib::core {

struct ImuIncrement {
  double t_s = 0.0;                                      ///< end of the interval
  double dt_s = 0.0;                                     ///< interval length
  Eigen::Vector3d dtheta_rad = Eigen::Vector3d::Zero();  ///< rotation vector, body, w.r.t. inertial
  Eigen::Vector3d dv_mps = Eigen::Vector3d::Zero();  ///< velocity increment, body at interval start
  double temp_c = 0.0;                               ///< sensor temperature, NaN if unknown
};

/// Reference orientation sample (table encoder or attitude log) for the same time axis.
struct TableSample {
  double t_s = 0.0;
  double outer_rad = 0.0;
  double inner_rad = 0.0;
  bool at_rest = false;
};

/// A recorded or simulated run in memory, independent of its on-disk archive.
using ImuSeries = std::vector<ImuIncrement>;

}  // namespace imucal::calib::core
