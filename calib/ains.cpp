#include "calib/ains.hpp"

#include <chrono>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "calib/ains_filter.hpp"
#include "calib/conventions.hpp"

namespace imucal::calib {

ParamSet default_prior_sigma() {
  ParamSet p;
  p.accel_bias_mps2.setConstant(5e-3 * kStandardGravity_mps2);  // 5 mg
  p.accel_M.setConstant(5000e-6);                               // 5000 ppm / 5 mrad
  p.gyro_bias_radps.setConstant(1.0 * kDegPerHourToRadPerSec);  // 1 deg/h
  p.gyro_M.setConstant(5000e-6);
  p.table_misalignment_rad.setConstant(1e-3);  // 1 mrad
  return p;
}

ParamSet effective_prior_sigma(const AinsOptions& opt) {
  ParamVector p = opt.prior_sigma.to_vector();
  const ParamVector d = default_prior_sigma().to_vector();
  for (int i = 0; i < ParamSet::kSize; ++i)
    if (!(p(i) > 0.0)) p(i) = d(i);
  return ParamSet::from_vector(p);
}

AinsResult calibrate_ains_detailed(const CalibrationInput& in, const AinsOptions& opt) {
  const auto t_start = std::chrono::steady_clock::now();
  const ains::PreparedInput pin = ains::prepare_input(in, opt);

  ains::PassConfig cfg;
  cfg.prior_sigma = effective_prior_sigma(opt);
  cfg.prior_mean = ParamVector::Zero();
  cfg.nominal = ParamSet::from_vector(cfg.prior_mean);

  AinsResult out;
  CalibrationResult& res = out.calibration;
  res.method = "ains";
  std::vector<ains::EpochRecord> epochs;
  ains::PassResult pass;
  double last_ratio = 0.0;
  for (int it = 1; it <= opt.max_iterations; ++it) {
    pass = ains::run_pass(pin, opt, cfg, &epochs);
    const ParamVector delta = ains::sensor_states_to_params(pass.x);
    const ParamCovariance cov = ains::sensor_cov_to_params(pass.P);
    if (!delta.allFinite() || !cov.allFinite())
      throw std::runtime_error("calibrate_ains: non-finite parameter update in pass " +
                               std::to_string(it));
    const ParamVector sigma = cov.diagonal().cwiseMax(1e-300).cwiseSqrt();
    last_ratio = delta.cwiseAbs().cwiseQuotient(sigma).maxCoeff();
    out.update_norm_sigma.push_back(last_ratio);
    cfg.nominal = ParamSet::from_vector(cfg.nominal.to_vector() + delta);
    res.cov = cov;
    res.iterations = it;
    if (last_ratio < opt.convergence_sigma_ratio) {
      res.converged = true;
      break;
    }
  }
  res.params = cfg.nominal;
  res.sigma = sigma_from_covariance(res.cov);
  out.num_updates = pass.num_updates;
  out.mean_nis = pass.nis_count ? pass.nis_sum / static_cast<double>(pass.nis_count) : 0.0;
  out.smoothed = ains::rts_smooth(epochs, &out.smoother_param_mismatch_sigma);

  if (!res.converged) {
    std::ostringstream os;
    os << "AINS did not converge in " << opt.max_iterations
       << " passes: last update max |dtheta|/sigma = " << last_ratio;
    res.warnings.push_back(os.str());
  }
  // Each scalar innovation has expectation 1 of ν²/s if the noise model fits; a mean far above
  // it means the data disagree with the model (unmodelled effects, wrong noise spec, bad aiding).
  if (out.mean_nis > 5.0) {
    std::ostringstream os;
    os << "innovations larger than the noise model predicts: mean NIS " << out.mean_nis
       << " (expected <= 1); sigma may be optimistic";
    res.warnings.push_back(os.str());
  }
  if (in.noise.gyro_bias_instability_radps > 0.0 || in.noise.accel_bias_instability_mps2 > 0.0)
    res.warnings.push_back(
        "noise model has bias instability; AINS models biases as random constants (paper §IV-A)");
  res.runtime_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  return out;
}

CalibrationResult calibrate_ains(const CalibrationInput& in, const AinsOptions& opt) {
  return calibrate_ains_detailed(in, opt).calibration;
}

}  // namespace imucal::calib
