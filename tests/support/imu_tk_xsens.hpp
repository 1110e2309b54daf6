#pragma once
// The real recording of tests/data/imu_tk_xsens (IMU-TK's Xsens test data, BSD): read as a new
// user's first import would be, with nominal values only — zero at 32768 counts, 1/6258 rad/s per
// gyro count (IMU-TK's own initial value) and a round 2.65 mm/s² per accelerometer count — so the
// gyros carry offsets of a few °/s and the scales are off by up to a quarter.
#include <gtest/gtest.h>

#include <array>
#include <cstdio>
#include <string>
#include <vector>

#include "calib/core/imu_increment.hpp"

namespace imucal::test_support {

constexpr double kZero_counts = 32768.0;
constexpr double kGyro_radps_per_count = 1.0 / 6258.0;
constexpr double kAccel_mps2_per_count = 2.65e-3;

/// One xz-compressed IMU-TK ".mat" file: rows of time (s) and three raw counts.
inline std::vector<std::array<double, 4>> read_mat(const std::string& name) {
  const std::string path = std::string(IMUCAL_SOURCE_DIR) + "/tests/data/imu_tk_xsens/" + name;
  FILE* p = ::popen(("xz -dc '" + path + "'").c_str(), "r");
  EXPECT_NE(p, nullptr) << path;
  std::vector<std::array<double, 4>> rows;
  std::array<double, 4> r{};
  while (p && std::fscanf(p, "%lf %lf %lf %lf", &r[0], &r[1], &r[2], &r[3]) == 4) rows.push_back(r);
  if (p) {
    EXPECT_EQ(::pclose(p), 0) << path;
  }
  return rows;
}

inline calib::core::ImuSeries read_imu_tk_xsens() {
  const auto acc = read_mat("xsens_acc.mat.xz");
  const auto gyro = read_mat("xsens_gyro.mat.xz");
  EXPECT_EQ(acc.size(), gyro.size());
  calib::core::ImuSeries imu;
  for (size_t k = 0; k < std::min(acc.size(), gyro.size()); ++k) {
    EXPECT_EQ(acc[k][0], gyro[k][0]) << "row " << k;
    calib::core::ImuIncrement s;
    s.t_s = gyro[k][0];
    s.dt_s = k == 0 ? 0.01 : gyro[k][0] - gyro[k - 1][0];
    for (int ax = 0; ax < 3; ++ax) {
      s.dtheta_rad(ax) = (gyro[k][ax + 1] - kZero_counts) * kGyro_radps_per_count * s.dt_s;
      s.dv_mps(ax) = (acc[k][ax + 1] - kZero_counts) * kAccel_mps2_per_count * s.dt_s;
    }
    imu.push_back(s);
  }
  return imu;
}

}  // namespace imucal::test_support
