#pragma once
// The calibration parameter set (ARCHITECTURE §3): one schema for truth, estimates and the
// database.
#include <Eigen/Core>
#include <array>
#include <string>
#include <vector>

namespace imucal::calib::core {

struct ParamSet {
  Eigen::Vector3d accel_bias_mps2 = Eigen::Vector3d::Zero();
  Eigen::Matrix3d accel_M =
      Eigen::Matrix3d::Zero();  ///< dM_a: diag scale error, off-diag misalignment
  Eigen::Vector3d gyro_bias_radps = Eigen::Vector3d::Zero();
  Eigen::Matrix3d gyro_M = Eigen::Matrix3d::Zero();                  ///< dM_g
  Eigen::Vector3d table_misalignment_rad = Eigen::Vector3d::Zero();  ///< ς, paper eq. 30-31

  static constexpr int kSize = 27;
  /// Flat order: accel_bias(3), accel_M row-major(9), gyro_bias(3), gyro_M row-major(9), ς(3).
  Eigen::Matrix<double, kSize, 1> to_vector() const;
  static ParamSet from_vector(const Eigen::Matrix<double, kSize, 1>& x);
};
using ParamVector = Eigen::Matrix<double, ParamSet::kSize, 1>;
using ParamCovariance = Eigen::Matrix<double, ParamSet::kSize, ParamSet::kSize>;

/// Groups used for reporting and Monte Carlo statistics.
enum class ParamGroup {
  kAccelBias,
  kAccelScale,
  kAccelMisalign,
  kGyroBias,
  kGyroScale,
  kGyroMisalign,
  kTableMisalign
};
constexpr int kNumParamGroups = 7;

struct ParamInfo {
  std::string name;  ///< e.g. "accel_M[0][1]" (JSON path-like, matches the parameter-set JSON)
  ParamGroup group;
  std::string human_unit;  ///< "µg", "ppm", "µrad", "deg/h", "arcsec"
  double si_to_human;      ///< multiply an SI value by this to get human units
};

/// Metadata for flat index i (0..26).
const ParamInfo& param_info(int i);
std::string group_name(ParamGroup g);

}  // namespace imucal::calib::core
