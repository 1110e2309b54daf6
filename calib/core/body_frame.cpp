#include "calib/core/body_frame.hpp"

#include <Eigen/SVD>
#include <stdexcept>

#include "calib/core/rotation.hpp"

namespace imucal::calib::core {

BodyFrameChange to_accel_symmetric_frame(const ParamSet& params) {
  const Eigen::Matrix3d A = Eigen::Matrix3d::Identity() + params.accel_M;
  if (!A.allFinite() || !(A.determinant() > 1e-6))
    throw std::invalid_argument(
        "body frame: I + accel_M is singular or reflects an axis (determinant " +
        std::to_string(A.determinant()) + "); no orthogonal sensor frame exists");
  // Polar decomposition from the SVD A = W Σ Vᵀ: S = W Σ Wᵀ, U = W Vᵀ, A Uᵀ = S.
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(A, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Matrix3d U = svd.matrixU() * svd.matrixV().transpose();
  BodyFrameChange out;
  out.R = U;
  out.params = params;
  const Eigen::Matrix3d S = A * U.transpose();
  out.params.accel_M = 0.5 * (S + S.transpose()) - Eigen::Matrix3d::Identity();
  out.params.gyro_M =
      (Eigen::Matrix3d::Identity() + params.gyro_M) * U.transpose() - Eigen::Matrix3d::Identity();
  return out;
}

Eigen::Vector3d housing_rotation_rad(const ParamSet& params) {
  return matrix_to_rotvec(to_accel_symmetric_frame(params).R);
}

CalibrationResult in_accel_symmetric_frame(const CalibrationResult& result) {
  if (result.body_frame == BodyFrame::kAccelSymmetric) return result;
  CalibrationResult out = result;
  out.params = to_accel_symmetric_frame(result.params).params;
  // Jacobian by central differences (the map is smooth; steps far below any parameter's size).
  ParamCovariance J = ParamCovariance::Identity();
  const ParamVector x0 = result.params.to_vector();
  constexpr double kStep = 1e-7;
  for (int j = 0; j < ParamSet::kSize; ++j) {
    ParamVector xp = x0, xm = x0;
    xp(j) += kStep;
    xm(j) -= kStep;
    J.col(j) = (to_accel_symmetric_frame(ParamSet::from_vector(xp)).params.to_vector() -
                to_accel_symmetric_frame(ParamSet::from_vector(xm)).params.to_vector()) /
               (2.0 * kStep);
  }
  out.cov = J * result.cov * J.transpose();
  out.sigma = sigma_from_covariance(out.cov);
  out.body_frame = BodyFrame::kAccelSymmetric;
  return out;
}

}  // namespace imucal::calib::core
