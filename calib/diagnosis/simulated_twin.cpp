#include "calib/diagnosis/simulated_twin.hpp"

#include <random>

#include "calib/core/earth.hpp"
#include "calib/core/imu_error_model.hpp"
#include "calib/core/rotation.hpp"
#include "calib/effects/quantisation.hpp"

namespace imucal::calib::diagnosis {
using namespace calib::core;
using namespace calib::effects;

DiagnosisInput simulated_twin(const DiagnosisInput& real, const ParamSet& calibrated,
                              uint64_t seed) {
  DiagnosisInput twin = real;
  const CalibrationInput& in = real.cal;
  const EarthModel earth(in.site);
  const Eigen::Vector3d w_ie_n = earth.w_ie_n(), f_n = -earth.g_n();
  const Eigen::Matrix3d S = rotvec_to_matrix<double>(calibrated.table_misalignment_rad);
  const ImuErrorModel<double> em = ImuErrorModel<double>::from_params(calibrated);
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n01(0.0, 1.0);
  // The declared rounding, carried or per sample, as the real run's output had it.
  Quantiser q_th{in.noise.dtheta_lsb_rad, in.noise.lsb_rounding},
      q_dv{in.noise.dv_lsb_mps, in.noise.lsb_rounding};
  Eigen::Matrix3d C_prev = S * in.reference.front().C_bn_ref;
  for (size_t k = 0; k < in.imu.size(); ++k) {
    const double dt = in.imu[k].dt_s;
    const Eigen::Matrix3d C = S * in.reference[k].C_bn_ref;
    const Eigen::Vector3d dth = matrix_to_rotvec(
        C_prev.transpose() * rotvec_to_matrix<double>(Eigen::Vector3d(w_ie_n * dt)) * C);
    const Eigen::Vector3d dv = C_prev.transpose() * (f_n * dt + 0.5 * dt * dt * w_ie_n.cross(f_n));
    Eigen::Vector3d th = em.corrupt_dtheta(dth, dt), v = em.corrupt_dv(dv, dt);
    const double sth = in.noise.arw_rad_per_sqrt_s * std::sqrt(dt),
                 sv = in.noise.vrw_mps_per_sqrt_s * std::sqrt(dt);
    for (int i = 0; i < 3; ++i) {
      th(i) += sth * n01(rng);
      v(i) += sv * n01(rng);
    }
    twin.cal.imu[k].dtheta_rad = q_th.apply(th);
    twin.cal.imu[k].dv_mps = q_dv.apply(v);
    C_prev = C;
  }
  return twin;
}

}  // namespace imucal::calib::diagnosis
