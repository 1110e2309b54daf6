// The rests' attitudes of a table-free run (calib/diagnosis/gap_model.hpp): estimated from the data
// and the calibrated parameters, then refined as the residual model's own least-squares unknowns.
#include <Eigen/QR>
#include <cmath>

#include "calib/core/earth.hpp"
#include "calib/core/imu_error_model.hpp"
#include "calib/core/rotation.hpp"
#include "calib/diagnosis/gap_model.hpp"

namespace imucal::calib::diagnosis {
using namespace calib::core;
using namespace calib::effects;

namespace {

// Difference step of a rest's attitude unknowns: the residuals are linear in them far beyond it.
constexpr double kAttitudeStep_rad = 1e-6;
// Gauss-Newton steps of the rest attitudes with the calibration held (the first one may start a
// few degrees off in heading; each then roughly squares the error).
constexpr int kRefineIterations = 4;

/// The attitude whose body axes see "down" along -f_b (specific force at rest points up) and,
/// where given, north as the horizontal part of `north_hint_b`.
Eigen::Matrix3d level_attitude(const Eigen::Vector3d& f_b, const Eigen::Vector3d& north_hint_b) {
  const Eigen::Vector3d down = -f_b.normalized();
  Eigen::Vector3d north = north_hint_b - north_hint_b.dot(down) * down;
  if (north.norm() < 1e-6 * north_hint_b.norm() || !(north.norm() > 0.0)) {
    // No usable hint: the body axis farthest from vertical, levelled.
    int axis = 0;
    for (int i = 1; i < 3; ++i)
      if (std::abs(down(i)) < std::abs(down(axis))) axis = i;
    north = Eigen::Vector3d::Unit(axis) - down(axis) * down;
  }
  north.normalize();
  const Eigen::Vector3d east = down.cross(north);
  Eigen::Matrix3d C_nb;  // rows: north, east, down in body axes
  C_nb.row(0) = north.transpose();
  C_nb.row(1) = east.transpose();
  C_nb.row(2) = down.transpose();
  return C_nb;  // = C_bn, since C_bn maps body to navigation axes
}

}  // namespace

Eigen::Matrix3d GapModel::carry_attitude(const GapSegment& seg, const ParamSet& calibrated,
                                         const Eigen::Matrix3d& C_start) const {
  const ImuCompensator comp(calibrated);
  const Eigen::Vector3d w_ie_n = EarthModel(in_.site).w_ie_n();
  Eigen::Matrix3d C = C_start;
  for (size_t k = seg.begin; k < seg.end; ++k) {
    const ImuIncrement& x = in_.imu[k];
    C = advance_attitude(C, comp.dtheta(x.dtheta_rad, x.dt_s), w_ie_n * x.dt_s);
  }
  return orthonormalize(C);
}

void GapModel::estimate_rest_attitudes(const ParamSet& calibrated) {
  chain_rest_attitudes(calibrated);
  choose_common_heading(calibrated);
  build_covariances();
  refine_rest_attitudes(calibrated);
  build_covariances();  // the move blocks are rotated into the refined attitudes
}

// Rest 1 levelled on its specific force, north from its Earth rate (any heading will do: the
// common heading is chosen next); every later rest carried across the move before it by the gyros
// and levelled again on its own specific force (the heading kept).
void GapModel::chain_rest_attitudes(const ParamSet& calibrated) {
  const ImuCompensator comp(calibrated);
  rest_C_bn_.clear();
  for (size_t r = 0; r < rests_.size(); ++r) {
    const Eigen::Vector3d f_b = comp.dv(sums_[r].f_mean_raw, 1.0);
    if (r == 0) {
      rest_C_bn_.push_back(level_attitude(f_b, comp.dtheta(sums_[r].w_mean_raw, 1.0)));
      continue;
    }
    const GapSegment& move = segments_[2 * r - 1];  // rest, move, rest, ... (build_segments)
    const Eigen::Matrix3d C = carry_attitude(move, calibrated, rest_C_bn_[r - 1]);
    // North of the carried attitude, in body axes, as the hint: the heading carries over.
    rest_C_bn_.push_back(level_attitude(f_b, C.row(0).transpose()));
  }
}

// The common heading h (a rotation of every rest about the vertical) from the Earth rate the rests
// see, with the gyro biases refitted: ω̄_R = b + C_Rᵀ R_z(h)ᵀ ω_ie_n is linear in (b, cos h, sin h),
// weighted by each rest's length (its noise is ARW²/T).
void GapModel::choose_common_heading(const ParamSet& calibrated) {
  const ImuCompensator comp(calibrated);
  const EarthModel earth(in_.site);
  const Eigen::Vector3d w = earth.w_ie_n();
  const double w_h = std::hypot(w(0), w(1));
  if (!(w_h > 0.0)) return;  // at a pole: no horizontal Earth rate, no heading to choose
  const int n = static_cast<int>(rests_.size());
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(3 * n, 5);
  Eigen::VectorXd y(3 * n);
  for (int r = 0; r < n; ++r) {
    const double sw = std::sqrt(sums_[static_cast<size_t>(r)].T_s);
    const Eigen::Matrix3d Ct = rest_C_bn_[static_cast<size_t>(r)].transpose();
    const Eigen::Vector3d w_b = comp.dtheta(sums_[static_cast<size_t>(r)].w_mean_raw, 1.0);
    // R_z(h)ᵀ (w_h, 0, w_z) = (w_h cos h, -w_h sin h, w_z)
    y.segment<3>(3 * r) = sw * (w_b - Ct * Eigen::Vector3d(0.0, 0.0, w(2)));
    A.block<3, 3>(3 * r, 0) = sw * Eigen::Matrix3d::Identity();
    A.block<3, 1>(3 * r, 3) = sw * w_h * Ct.col(0);
    A.block<3, 1>(3 * r, 4) = -sw * w_h * Ct.col(1);
  }
  const Eigen::VectorXd x = A.colPivHouseholderQr().solve(y);
  if (!(std::hypot(x(3), x(4)) > 0.0)) return;
  const Eigen::Matrix3d Rz =
      rotvec_to_matrix<double>(Eigen::Vector3d(0.0, 0.0, std::atan2(x(4), x(3))));
  for (Eigen::Matrix3d& C : rest_C_bn_) C = Rz * C;
}

Eigen::MatrixXd GapModel::attitude_jacobian(const ParamSet& base) const {
  const int m = attitude_unknowns();
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(rows(), m);
  if (m == 0) return J;
  Eigen::VectorXd d = Eigen::VectorXd::Zero(m);
  const Effects none;
  for (size_t r = 0; r < rests_.size(); ++r) {
    const std::vector<size_t> segs = segments_of_rest(r);
    std::vector<Eigen::Matrix<double, 6, 1>> r0(segs.size());
    for (size_t i = 0; i < segs.size(); ++i)
      segment_residuals(segs[i], base, none, nullptr, r0[i].data());
    for (int c = 0; c < 3; ++c) {
      const int col = 3 * static_cast<int>(r) + c;
      d(col) = kAttitudeStep_rad;
      for (size_t i = 0; i < segs.size(); ++i) {
        Eigen::Matrix<double, 6, 1> r1;
        segment_residuals(segs[i], base, none, &d, r1.data());
        J.block<6, 1>(6 * static_cast<int>(segs[i]), col) = (r1 - r0[i]) / kAttitudeStep_rad;
      }
      d(col) = 0.0;
    }
  }
  return J;
}

// Gauss-Newton on the rests' attitudes alone, the calibration held: the diagnosis then fits the
// base parameters and the remaining small rotations jointly, linearised here.
void GapModel::refine_rest_attitudes(const ParamSet& calibrated) {
  const Effects none;
  for (int it = 0; it < kRefineIterations; ++it) {
    const Eigen::VectorXd r = whiten(residuals(calibrated, none));
    const Eigen::MatrixXd J = whiten(attitude_jacobian(calibrated));
    const Eigen::VectorXd d = J.colPivHouseholderQr().solve(-r);
    if (!d.allFinite()) return;
    for (size_t k = 0; k < rests_.size(); ++k)
      rest_C_bn_[k] = orthonormalize(
          rotvec_to_matrix<double>(Eigen::Vector3d(d.segment<3>(3 * static_cast<int>(k)))) *
          rest_C_bn_[k]);
    if (d.cwiseAbs().maxCoeff() < 1e-9) return;
  }
}

}  // namespace imucal::calib::diagnosis
