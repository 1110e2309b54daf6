// The accel-symmetric body frame (calib/core/body_frame.hpp): the transformed parameters describe
// the same sensor outputs for a body rotated by R, I + M_a' is symmetric, and the covariance
// follows the transformation (checked against sampling, not against the code's own Jacobian).
#include "calib/core/body_frame.hpp"

#include <gtest/gtest.h>

#include <random>

#include "calib/core/rotation.hpp"
#include "calib/sim/truth_sim.hpp"

namespace imucal::calib {
using namespace imucal::calib::core;
using namespace imucal::calib::effects;
namespace {

TEST(BodyFrame, SameSensorOutputsInTheRotatedFrameAndMaSymmetric) {
  const ParamSet p = default_unit().params;
  const BodyFrameChange ch = to_accel_symmetric_frame(p);
  const Eigen::Matrix3d& Ma = ch.params.accel_M;
  EXPECT_LT((Ma - Ma.transpose()).cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_LT((ch.R.transpose() * ch.R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff(), 1e-14);
  EXPECT_NEAR(ch.R.determinant(), 1.0, 1e-14);
  // f~ = (I + M_a) f_b + b_a  must equal  (I + M_a') f_b' + b_a  with f_b' = R f_b; same for ω.
  const Eigen::Vector3d f_b(0.3, -9.1, 2.2), w_b(1e-3, 2e-4, -5e-4);
  const Eigen::Matrix3d I = Eigen::Matrix3d::Identity();
  EXPECT_LT(((I + p.accel_M) * f_b - (I + ch.params.accel_M) * (ch.R * f_b)).norm(),
            1e-13);  // round-off on |f| ≈ 9.4
  EXPECT_LT(((I + p.gyro_M) * w_b - (I + ch.params.gyro_M) * (ch.R * w_b)).norm(), 1e-18);
  EXPECT_EQ(ch.params.accel_bias_mps2, p.accel_bias_mps2);
  EXPECT_EQ(ch.params.gyro_bias_radps, p.gyro_bias_radps);
  // The rotation is the antisymmetric part of M_a to first order (|R - I| ~ |skew(M_a)|).
  const Eigen::Vector3d rv = housing_rotation_rad(p);
  const Eigen::Matrix3d S = 0.5 * (p.accel_M - p.accel_M.transpose());
  EXPECT_NEAR(rv.norm(), Eigen::Vector3d(S(2, 1), S(0, 2), S(1, 0)).norm(), 2e-6);
}

TEST(BodyFrame, AlreadySymmetricIsUnchanged) {
  ParamSet p = default_unit().params;
  p.accel_M = 0.5 * (p.accel_M + p.accel_M.transpose()).eval();
  const BodyFrameChange ch = to_accel_symmetric_frame(p);
  EXPECT_LT((ch.R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_LT((ch.params.gyro_M - p.gyro_M).cwiseAbs().maxCoeff(), 1e-15);
}

TEST(BodyFrame, CovarianceMatchesSampling) {
  CalibrationResult r;
  r.params = default_unit().params;
  ParamVector sd = ParamVector::Constant(50e-6);
  sd.segment<3>(0).setConstant(1e-4);
  sd.segment<3>(12).setConstant(1e-7);
  r.cov = sd.cwiseProduct(sd).asDiagonal();
  r.sigma = sigma_from_covariance(r.cov);
  const CalibrationResult t = in_accel_symmetric_frame(r);
  EXPECT_EQ(t.body_frame, BodyFrame::kAccelSymmetric);
  std::mt19937_64 rng(3);
  std::normal_distribution<double> n01;
  const int N = 4000;
  ParamVector mean = ParamVector::Zero();
  std::vector<ParamVector> xs;
  for (int k = 0; k < N; ++k) {
    ParamVector x = r.params.to_vector();
    for (int i = 0; i < ParamSet::kSize; ++i) x(i) += sd(i) * n01(rng);
    xs.push_back(to_accel_symmetric_frame(ParamSet::from_vector(x)).params.to_vector());
    mean += xs.back() / N;
  }
  ParamVector var = ParamVector::Zero();
  for (const auto& x : xs) var += (x - mean).cwiseAbs2() / (N - 1);
  for (int i = 0; i < ParamSet::kSize; ++i) {
    const double s_emp = std::sqrt(var(i)), s_lin = t.sigma.to_vector()(i);
    EXPECT_NEAR(s_emp / s_lin, 1.0, 0.06) << param_info(i).name;
  }
  // Transforming twice changes nothing.
  const CalibrationResult t2 = in_accel_symmetric_frame(t);
  EXPECT_EQ(t2.params.to_vector(), t.params.to_vector());
}

TEST(BodyFrame, RefusesAReflectedAxis) {
  ParamSet p;
  p.accel_M(1, 1) = -2.0;  // I + M_a flips y: no rotation makes it symmetric positive
  try {
    to_accel_symmetric_frame(p);
    ADD_FAILURE() << "a reflected axis must be refused";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("determinant"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace imucal::calib
