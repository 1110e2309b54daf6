#pragma once
// The IMU error model of paper eq. 18 and 23, templated on the scalar so the simulator (double)
// and Ceres cost functions (Jet) run the same code.
#include <Eigen/Core>
#include <Eigen/LU>

#include "calib/core/param_set.hpp"

namespace imucal::calib::core {

template <typename T>
struct ImuErrorModel {
  Eigen::Matrix<T, 3, 1> b_a = Eigen::Matrix<T, 3, 1>::Zero();
  Eigen::Matrix<T, 3, 3> M_a = Eigen::Matrix<T, 3, 3>::Zero();
  Eigen::Matrix<T, 3, 1> b_g = Eigen::Matrix<T, 3, 1>::Zero();
  Eigen::Matrix<T, 3, 3> M_g = Eigen::Matrix<T, 3, 3>::Zero();

  static ImuErrorModel from_params(const ParamSet& p) {
    ImuErrorModel m;
    m.b_a = p.accel_bias_mps2.cast<T>();
    m.M_a = p.accel_M.cast<T>();
    m.b_g = p.gyro_bias_radps.cast<T>();
    m.M_g = p.gyro_M.cast<T>();
    return m;
  }

  /// Eq. 18 on an increment: dv~ = dv + b_a dt + dM_a dv.
  Eigen::Matrix<T, 3, 1> corrupt_dv(const Eigen::Matrix<T, 3, 1>& dv, T dt_s) const {
    return dv + b_a * dt_s + M_a * dv;
  }
  /// Eq. 23 on an increment: dθ~ = dθ + b_g dt + dM_g dθ.
  Eigen::Matrix<T, 3, 1> corrupt_dtheta(const Eigen::Matrix<T, 3, 1>& dth, T dt_s) const {
    return dth + b_g * dt_s + M_g * dth;
  }
  /// Inverse of eq. 18: dv = (I + dM_a)^-1 (dv~ - b_a dt). (For many samples with fixed
  /// parameters use ImuCompensator, which inverts once.)
  Eigen::Matrix<T, 3, 1> compensate_dv(const Eigen::Matrix<T, 3, 1>& dv_meas, T dt_s) const {
    const Eigen::Matrix<T, 3, 3> A = Eigen::Matrix<T, 3, 3>::Identity() + M_a;
    return A.inverse() * (dv_meas - b_a * dt_s);
  }
  /// Inverse of eq. 23.
  Eigen::Matrix<T, 3, 1> compensate_dtheta(const Eigen::Matrix<T, 3, 1>& dth_meas, T dt_s) const {
    const Eigen::Matrix<T, 3, 3> A = Eigen::Matrix<T, 3, 3>::Identity() + M_g;
    return A.inverse() * (dth_meas - b_g * dt_s);
  }
};

/// The inverse error model with (I + dM)^-1 computed once: for compensating whole runs with fixed
/// parameters (the per-sample 3x3 inversion otherwise costs as much as a strapdown step).
struct ImuCompensator {
  Eigen::Vector3d b_a = Eigen::Vector3d::Zero(), b_g = Eigen::Vector3d::Zero();
  Eigen::Matrix3d A_a_inv = Eigen::Matrix3d::Identity(), A_g_inv = Eigen::Matrix3d::Identity();

  explicit ImuCompensator(const ImuErrorModel<double>& m)
      : b_a(m.b_a),
        b_g(m.b_g),
        A_a_inv((Eigen::Matrix3d::Identity() + m.M_a).inverse()),
        A_g_inv((Eigen::Matrix3d::Identity() + m.M_g).inverse()) {}
  explicit ImuCompensator(const ParamSet& p)
      : ImuCompensator(ImuErrorModel<double>::from_params(p)) {}

  Eigen::Vector3d dv(const Eigen::Vector3d& dv_meas, double dt_s) const {
    return A_a_inv * (dv_meas - b_a * dt_s);
  }
  Eigen::Vector3d dtheta(const Eigen::Vector3d& dth_meas, double dt_s) const {
    return A_g_inv * (dth_meas - b_g * dt_s);
  }
};

}  // namespace imucal::calib::core
