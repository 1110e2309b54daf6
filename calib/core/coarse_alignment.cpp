#include "calib/core/coarse_alignment.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

#include "calib/core/conventions.hpp"
#include "calib/core/imu_error_model.hpp"
#include "calib/core/readable_number.hpp"
#include "calib/core/rotation.hpp"

namespace imucal::calib::core {

namespace {

[[noreturn]] void fail(const std::string& what) {
  throw std::invalid_argument("initial alignment: " + what);
}

/// Orthonormal triad of a primary and a secondary vector (Gram–Schmidt), as matrix columns.
Eigen::Matrix3d triad(const Eigen::Vector3d& p, const Eigen::Vector3d& s) {
  const Eigen::Vector3d e1 = p.normalized();
  const Eigen::Vector3d s_perp = s - s.dot(e1) * e1;
  const Eigen::Vector3d e2 = s_perp.normalized();
  Eigen::Matrix3d T;
  T << e1, e2, e1.cross(e2);
  return T;
}

}  // namespace

CoarseAlignment coarse_align(const ImuSeries& imu, size_t begin, size_t end, const Site& site,
                             const ParamSet& nominal, double vrw_mps_per_sqrt_s,
                             double min_window_s) {
  if (!(begin < end && end <= imu.size())) fail("empty or invalid sample window");
  const double T = imu[end - 1].t_s - imu[begin].t_s;
  if (!(T >= min_window_s))
    fail("the first rest period lasts " + seconds_text(T) + "; " +
         (min_window_s >= 10.0 ? "levelling and gyrocompassing need" : "levelling needs") +
         " at least " + seconds_text(min_window_s) + " at rest");
  if (std::abs(site.lat_rad) > 0.5 * kPi - kDegToRad)
    fail("latitude within 1 deg of a pole: no horizontal Earth rate to find north");

  const EarthModel earth(site);
  const Eigen::Vector3d w_ie_n = earth.w_ie_n();
  const Eigen::Vector3d f_n(0.0, 0.0, -earth.gravity_mps2());
  const ImuCompensator comp(nominal);
  const double t0 = imu[begin].t_s;
  const double t_mid = t0 + 0.5 * T;

  // Integrate both sides sample by sample: u in b0 (from the data), W in i0 (analytic).
  Eigen::Matrix3d C_b0_b = Eigen::Matrix3d::Identity();
  Eigen::Vector3d u1 = Eigen::Vector3d::Zero(), u2 = u1, W1 = u1, W2 = u1;
  for (size_t k = begin + 1; k < end; ++k) {
    const ImuIncrement& s = imu[k];
    const Eigen::Vector3d dv_b0 = C_b0_b * comp.dv(s.dv_mps, s.dt_s);
    C_b0_b = C_b0_b * rotvec_to_matrix<double>(comp.dtheta(s.dtheta_rad, s.dt_s));
    const double tau = s.t_s - 0.5 * s.dt_s - t0;
    const Eigen::Vector3d dW =
        rotvec_to_matrix<double>(Eigen::Vector3d(w_ie_n * tau)) * f_n * s.dt_s;
    const bool first_half = s.t_s - 0.5 * s.dt_s < t_mid;
    (first_half ? u1 : u2) += dv_b0;
    (first_half ? W1 : W2) += dW;
  }
  const Eigen::Vector3d u_p = u1 + u2, W_p = W1 + W2, u_s = u2 - u1, W_s = W2 - W1;
  // At rest |u_p| ≈ g T; the secondary pairs' parts normal to the primary must not vanish.
  if (!(std::abs(u_p.norm() / (earth.gravity_mps2() * T) - 1.0) < 0.05))
    fail("the mean specific force over the first rest is not gravity: the unit was not at rest");
  const double ws_perp = (W_s - W_s.dot(W_p.normalized()) * W_p.normalized()).norm();
  if (!(ws_perp > 0.0) || !(u_s - u_s.dot(u_p.normalized()) * u_p.normalized()).allFinite())
    fail("no Earth rotation seen over the window");

  // C_b0_i0 maps i0 to b0: triad_b = C_b0_i0 triad_i.  At the window start i0 = n.
  const Eigen::Matrix3d C_b0_i0 = triad(u_p, u_s) * triad(W_p, W_s).transpose();
  CoarseAlignment out;
  out.C_bn = orthonormalize(Eigen::Matrix3d(C_b0_i0.transpose()));
  out.window_s = T;
  // Noise of the half-sum difference: two independent random walks of T/2 each.
  out.heading_noise_sigma_rad = vrw_mps_per_sqrt_s * std::sqrt(T) / ws_perp;
  return out;
}

}  // namespace imucal::calib::core
