#include "calib/nlsq/nlsq_preprocess.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

#include "calib/core/earth.hpp"
#include "calib/core/imu_error_model.hpp"
#include "calib/core/rotation.hpp"

namespace imucal::calib::nlsq {
using namespace calib::core;

namespace {

/// Right Jacobian of exp: exp([(a + δ)×]) ≈ exp([a×]) exp([J_r(a) δ ×]).
Eigen::Matrix3d right_jacobian(const Eigen::Vector3d& a) {
  const double th2 = a.squaredNorm();
  const Eigen::Matrix3d K = skew<double>(a);
  double c1, c2;  // (1 - cos θ)/θ², (θ - sin θ)/θ³
  if (th2 < 1e-6) {
    c1 = 0.5 - th2 / 24.0 + th2 * th2 / 720.0;
    c2 = 1.0 / 6.0 - th2 / 120.0 + th2 * th2 / 5040.0;
  } else {
    const double th = std::sqrt(th2);
    c1 = (1.0 - std::cos(th)) / th2;
    c2 = (th - std::sin(th)) / (th2 * th);
  }
  return Eigen::Matrix3d::Identity() - c1 * K + c2 * K * K;
}

// Re-orthonormalise the running product this often: round-off grows ~1e-16 per step.
constexpr size_t kOrthonormaliseEvery = 256;

}  // namespace

std::vector<NlsqRestMean> nlsq_rest_means(const CalibrationInput& in,
                                          const std::vector<RestPeriod>& rests) {
  std::vector<NlsqRestMean> out;
  out.reserve(rests.size());
  // The declared dv rounding (noise_model.hpp): white beside VRW when rounded per sample, one
  // residue at each end of the rest's sum when carried.
  const NoiseModel& nm = in.noise;
  const double vrw2 = nm.vrw_mps_per_sqrt_s * nm.vrw_mps_per_sqrt_s +
                      rounding_white_density(nm.dv_lsb_mps, nm.lsb_rounding, in.imu.front().dt_s);
  const double q_dv = rounding_end_residues(nm.dv_lsb_mps, nm.lsb_rounding);
  for (const RestPeriod& p : rests) {
    NlsqRestMean r;
    r.begin = p.begin;
    r.end = p.end;
    r.mid = p.begin + p.size() / 2;
    // long double: a 100-s rest sums ~1e4 increments of ~0.1 m/s; the mean must stay exact to
    // far below the 1e-6 relative level of the smallest parameter effects.
    long double sum_dv[3] = {0.0L, 0.0L, 0.0L};
    long double s1 = 0.0L, s2 = 0.0L, s3 = 0.0L;
    for (size_t k = p.begin; k < p.end; ++k) {
      const ImuIncrement& s = in.imu[k];
      for (int i = 0; i < 3; ++i) sum_dv[i] += s.dv_mps(i);
      const long double dt = s.dt_s;
      s1 += dt;
      s2 += dt * dt;
      s3 += dt * dt * dt;
    }
    r.T_s = static_cast<double>(s1);
    for (int i = 0; i < 3; ++i) r.f_meas_b(i) = static_cast<double>(sum_dv[i] / s1);
    r.h1_s = static_cast<double>(s2 / (2.0L * s1));
    r.h2_s2 = static_cast<double>(s3 / (6.0L * s1));
    r.C_bn_ref = in.reference[r.mid].C_bn_ref;
    r.sigma_f_mps2 = std::sqrt(vrw2 / r.T_s + q_dv / (r.T_s * r.T_s));
    out.push_back(r);
  }
  return out;
}

Eigen::Matrix3d nlsq_propagate_body(const ImuSeries& imu, size_t begin, size_t end,
                                    const ParamSet& theta) {
  const ImuCompensator em(theta);
  Eigen::Matrix3d P = Eigen::Matrix3d::Identity();
  for (size_t k = begin; k < end; ++k) {
    const Eigen::Vector3d dth = em.dtheta(imu[k].dtheta_rad, imu[k].dt_s);
    P = P * rotvec_to_matrix<double>(dth);
    if ((k - begin) % kOrthonormaliseEvery == kOrthonormaliseEvery - 1) P = orthonormalize(P);
  }
  return orthonormalize(P);
}

NlsqRotation nlsq_linearise_rotation(const CalibrationInput& in,
                                     const std::vector<NlsqRestMean>& rests, size_t rest_a,
                                     size_t rest_b, const ParamSet& theta0, NlsqSpan span) {
  const NlsqRestMean& A = rests.at(rest_a);
  const NlsqRestMean& B = rests.at(rest_b);
  NlsqRotation rot;
  rot.rest_a = rest_a;
  rot.rest_b = rest_b;
  switch (span) {
    case NlsqSpan::kMidRestToMidRest:
      rot.begin = A.mid;
      rot.end = B.mid;
      break;
    case NlsqSpan::kRestEndToRestBegin:
      rot.begin = A.end;
      rot.end = B.begin;
      break;
    case NlsqSpan::kWholeRest:
      if (rest_a != rest_b)
        throw std::invalid_argument(
            "nlsq_linearise_rotation: a whole-rest span needs rest_a == rest_b");
      rot.begin = A.begin;
      rot.end = A.end;
      break;
  }
  if (!(rot.begin < rot.end && rot.end <= in.imu.size()))
    throw std::invalid_argument("nlsq_linearise_rotation: empty or out-of-range span [" +
                                std::to_string(rot.begin) + ", " + std::to_string(rot.end) +
                                ") (rests must be in time order)");
  rot.theta_g0.head<3>() = theta0.gyro_bias_radps;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) rot.theta_g0(3 + 3 * r + c) = theta0.gyro_M(r, c);
  rot.rotation_angle_rad = matrix_to_rotvec(A.C_bn_ref.transpose() * B.C_bn_ref).norm();

  const ImuErrorModel<double> em = ImuErrorModel<double>::from_params(theta0);
  const Eigen::Matrix3d A0 = (Eigen::Matrix3d::Identity() + em.M_g).inverse();
  Eigen::Matrix3d P = Eigen::Matrix3d::Identity();
  Eigen::Matrix<double, 3, 12> S = Eigen::Matrix<double, 3, 12>::Zero();
  long double T = 0.0L;
  for (size_t k = rot.begin; k < rot.end; ++k) {
    const double dt = in.imu[k].dt_s;
    T += dt;
    const Eigen::Vector3d dth = A0 * (in.imu[k].dtheta_rad - em.b_g * dt);  // eq. 23 inverted
    P = P * rotvec_to_matrix<double>(dth);
    if ((k - rot.begin) % kOrthonormaliseEvery == kOrthonormaliseEvery - 1) P = orthonormalize(P);
    // Sensitivity of this step's perturbation, carried in the start frame (P_k J_r A0); δ_k =
    // -A0 (δb_g dt + δdM_g dθ_k), and δdM_g dθ_k = K(dθ_k) vec_rowmajor(δdM_g).
    const Eigen::Matrix3d G = P * right_jacobian(dth) * A0;
    S.leftCols<3>() += G * dt;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) S.col(3 + 3 * i + j) += G.col(i) * dth(j);
  }
  P = orthonormalize(P);
  rot.dC_b0 = P;
  rot.J_b = -P.transpose() * S;
  rot.T_s = static_cast<double>(T);
  const Eigen::Vector3d w_ie_n = EarthModel(in.site).w_ie_n();
  rot.E_n = rotvec_to_matrix<double>(Eigen::Vector3d(-w_ie_n * rot.T_s));
  // ARW: each increment's noise is rotated into the end frame by an orthogonal matrix, so the
  // accumulated attitude noise stays isotropic with variance ARW²·T; a carried rounding leaves
  // one LSB residue at each end, a per-sample one adds its white density to ARW².
  const NoiseModel& nm = in.noise;
  const double arw2 =
      nm.arw_rad_per_sqrt_s * nm.arw_rad_per_sqrt_s +
      rounding_white_density(nm.dtheta_lsb_rad, nm.lsb_rounding, in.imu.front().dt_s);
  rot.sigma_psi_rad =
      std::sqrt(arw2 * rot.T_s + rounding_end_residues(nm.dtheta_lsb_rad, nm.lsb_rounding));
  return rot;
}

}  // namespace imucal::calib::nlsq
