#include "calib/ains/ains.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "calib/ains/ains_filter.hpp"
#include "calib/core/coarse_alignment.hpp"
#include "calib/core/conventions.hpp"
#include "calib/core/readable_number.hpp"
#include "calib/core/rotation.hpp"
#include "calib/core/unit_grade.hpp"

namespace imucal::calib::ains {
using namespace calib::core;

ParamSet default_prior_sigma() {
  ParamSet p;
  p.accel_bias_mps2.setConstant(5e-3 * kStandardGravity_mps2);  // 5 mg
  p.accel_M.setConstant(5000e-6);                               // 5000 ppm / 5 mrad
  p.gyro_bias_radps.setConstant(1.0 * kDegPerHourToRadPerSec);  // 1 deg/h
  p.gyro_M.setConstant(5000e-6);
  p.table_misalignment_rad.setConstant(1e-3);  // 1 mrad
  return p;
}

ParamSet prior_sigma_for_grade(const UnitPrior& prior) {
  if (prior.plain_navigation()) return default_prior_sigma();
  const GradePrior g = prior.envelope();
  ParamSet p = default_prior_sigma();
  p.accel_bias_mps2.setConstant(g.accel_bias_mps2);
  p.gyro_bias_radps.setConstant(g.gyro_bias_radps);
  p.accel_M.setConstant(g.misalignment_rad);
  p.gyro_M.setConstant(g.misalignment_rad);
  p.accel_M.diagonal().setConstant(g.scale);
  p.gyro_M.diagonal().setConstant(g.scale);
  return p;
}

ParamSet effective_prior_sigma(const AinsOptions& opt, const UnitPrior& prior) {
  ParamVector p = opt.prior_sigma.to_vector();
  const ParamVector d = prior_sigma_for_grade(prior).to_vector();
  for (int i = 0; i < ParamSet::kSize; ++i)
    if (!(p(i) > 0.0)) p(i) = d(i);
  return ParamSet::from_vector(p);
}

namespace {

/// What a field result cannot say, stated with it (issue #9: "say so in the output").
void describe_field_frame(CalibrationResult& res) {
  res.body_frame = BodyFrame::kAccelSymmetric;
  for (int i = 24; i < ParamSet::kSize; ++i) res.observable[static_cast<size_t>(i)] = false;
  const std::string where = res.setting == Setting::kSea ? "at sea" : "on land";
  res.unobservable_notes.push_back(
      "housing orientation: not observable " + where +
      " (no attitude reference); misalignments are relative to the accelerometer triad's own "
      "orthogonal frame (accel_M symmetric), not to the housing");
  res.unobservable_notes.push_back("table misalignment: no table " + where + ", not estimated");
}

/// The smoothed ψ(0) of a pass in units of its σ (how far the initial attitude still moves).
double initial_attitude_update_sigma(const SmoothedNav& s0) {
  return s0.psi_rad.cwiseAbs().cwiseQuotient(s0.sigma_psi_rad.cwiseMax(1e-300)).maxCoeff();
}

}  // namespace

namespace {

/// The initial heading of a unit that cannot gyrocompass, by likelihood. Below navigation grade
/// the gyros' residual bias is of the order of the Earth rate: the coarse alignment's heading is
/// anywhere (off by up to 180° on simulated MEMS runs), and from there the passes do not find it —
/// the heading is a flat valley for a linearised filter — while the mis-projected Earth rate, a
/// horizontal rate error fixed in the navigation frame, biases the accelerometer terms by up to
/// 6σ (tests/calib/ains_grade_test.cpp). One pass from each of 12 headings 30° apart, the prior
/// on ψ(0) centred on the candidate (the coarse heading means nothing here); the χ² of the
/// innovations is a smooth bowl about the truth (Δχ² ≈ 60 between the best heading and its
/// opposite on a 6-minute hand-placed run), so a parabola through the best and its neighbours
/// finds its bottom to a few degrees. Returns the chosen attitude.
Eigen::Matrix3d search_initial_heading(const ains::PreparedInput& pin, const AinsOptions& opt,
                                       ains::PassConfig cfg, const Eigen::Matrix3d& C_coarse) {
  constexpr int kCandidates = 12;
  constexpr double kStep_rad = 2.0 * kPi / kCandidates;
  auto turned = [&](double dpsi_rad) {
    return Eigen::Matrix3d(rotvec_to_matrix<double>(Eigen::Vector3d(0.0, 0.0, dpsi_rad)) *
                           C_coarse);
  };
  auto chi2 = [&](double dpsi_rad) {
    cfg.C_bn0 = turned(dpsi_rad);
    cfg.psi0_prior_mean.setZero();
    return ains::run_pass(pin, opt, cfg, nullptr).nis_sum;
  };
  std::array<double, kCandidates> c{};
  int best = 0;
  for (int i = 0; i < kCandidates; ++i) {
    c[static_cast<size_t>(i)] = chi2(i * kStep_rad);
    if (c[static_cast<size_t>(i)] < c[static_cast<size_t>(best)]) best = i;
  }
  const double lo = c[static_cast<size_t>((best + kCandidates - 1) % kCandidates)];
  const double mid = c[static_cast<size_t>(best)];
  const double hi = c[static_cast<size_t>((best + 1) % kCandidates)];
  const double curvature = lo - 2.0 * mid + hi;
  const double shift = curvature > 0.0 ? std::clamp(0.5 * (lo - hi) / curvature, -0.5, 0.5) : 0.0;
  const double dpsi_rad = (best + shift) * kStep_rad;
  return chi2(dpsi_rad) <= mid ? turned(dpsi_rad) : turned(best * kStep_rad);
}

/// Between passes in the field settings: the nominal's initial attitude re-centred on the
/// smoothed one (the prior stays centred on the coarse alignment), and on land below navigation
/// grade the next pass's attitude track (PassConfig::attitude_track: the smoothed attitude of every
/// epoch). Once a track exists only the initial tilt is re-centred, not the heading: a MEMS heading
/// is a flat valley (σ of tens of degrees), and re-centring it while a track follows the last pass
/// walked it by degrees a pass and the parameters by 0.01-0.04σ a pass without end (6 of 10
/// hand-placed runs unconverged after 8 passes, one still stepping 0.03σ after 40 and its heading
/// 73° off; docs/validation/ains_mems_land.md). The heading stays a state of the filter,
/// estimated about the heading the first pass smoothed.
void recentre_on_smoothed(const std::vector<SmoothedNav>& sm, bool track_attitude,
                          const Eigen::Matrix3d& coarse_C_bn, ains::PassConfig& cfg,
                          std::vector<Eigen::Matrix3d>& track) {
  if (track.empty()) {
    cfg.C_bn0 = sm.front().nav.C_bn;
  } else {
    Eigen::Vector3d tilt_rad = matrix_to_rotvec(sm.front().nav.C_bn * cfg.C_bn0.transpose());
    tilt_rad(2) = 0.0;  // ψ is an n-frame angle: its down component is the heading
    cfg.C_bn0 = orthonormalize(rotvec_to_matrix<double>(tilt_rad) * cfg.C_bn0);
  }
  cfg.psi0_prior_mean = matrix_to_rotvec(coarse_C_bn * cfg.C_bn0.transpose());
  if (!track_attitude) return;
  track.resize(sm.size());
  for (size_t i = 0; i < sm.size(); ++i) track[i] = sm[i].nav.C_bn;
  cfg.attitude_track = &track;
}

/// The iterated passes (steps 1-4 of ains.hpp): each pass linearises about the last estimate
/// until every update is below convergence_sigma_ratio·σ. `epochs` receives the last pass's
/// epochs when `keep_epochs` (the field settings need them in every pass: the smoother re-centres
/// the initial attitude); otherwise no epoch is recorded, which is most of a factory pass's
/// memory and a quarter of its time.
ains::PassResult iterate_passes(const ains::PreparedInput& pin, const AinsOptions& opt,
                                bool keep_epochs, ains::PassConfig& cfg, AinsResult& out,
                                std::vector<ains::EpochRecord>& epochs) {
  const bool field = pin.in->setting != Setting::kFactory;
  // A gyro that cannot gyrocompass (every grade but navigation) leaves the initial heading a
  // flat valley for the linearised passes: it keeps stepping by a tenth of its (optimistic) σ a
  // pass while the parameters have settled. Its heading comes from the likelihood search
  // (search_initial_heading), and the parameters alone decide convergence; navigation grade
  // holds the initial attitude to the same bar as the parameters.
  const bool attitude_decides = pin.in->grade == Grade::kNavigation;
  // On land below navigation grade each pass's nominal tilt follows the last pass's smoothed
  // attitude (PassConfig::attitude_track): a MEMS tilt σ stays near the filter's feedback gate for
  // minutes. Not at sea: on tactical hand-placed sea runs the heading then settled up to 42° off
  // and the gyro biases' RMS(error/σ) rose from 0.99 to 2.1 (6 runs; land: docs/validation/
  // ains_mems_land.md).
  const bool track_attitude = pin.in->setting == Setting::kLand && !attitude_decides;
  std::vector<Eigen::Matrix3d> track;
  CalibrationResult& res = out.calibration;
  ains::PassResult pass;
  for (int it = 1; it <= opt.max_iterations; ++it) {
    pass = ains::run_pass(pin, opt, cfg, keep_epochs || field ? &epochs : nullptr);
    const ParamVector delta = ains::sensor_states_to_params(pass.x);
    const ParamCovariance cov = ains::sensor_cov_to_params(pass.P);
    if (!delta.allFinite() || !cov.allFinite())
      throw std::runtime_error("AINS: non-finite parameter update in pass " + std::to_string(it));
    const ParamVector sigma = cov.diagonal().cwiseMax(1e-300).cwiseSqrt();
    double ratio = delta.cwiseAbs().cwiseQuotient(sigma).maxCoeff();
    if (field) {
      // The initial attitude is a state like the parameters: re-centre the nominal on it.
      const std::vector<SmoothedNav> sm = ains::rts_smooth(epochs, nullptr);
      if (attitude_decides) ratio = std::max(ratio, initial_attitude_update_sigma(sm.front()));
      recentre_on_smoothed(sm, track_attitude, out.coarse_C_bn, cfg, track);
    }
    out.update_norm_sigma.push_back(ratio);
    cfg.nominal = ParamSet::from_vector(cfg.nominal.to_vector() + delta);
    res.cov = cov;
    res.iterations = it;
    if (ratio < opt.convergence_sigma_ratio) {
      res.converged = true;
      break;
    }
  }
  return pass;
}

/// Innovations beyond this mean NIS say the noise model does not describe the data.
constexpr double kNisMisfit = 5.0;

/// A real MEMS unit's noise is not the white noise the filter models (coloured by the sensor's own
/// filter, a hand's tremor in the rests): on the corpus' MPU-9150 units the mean NIS is 40, and the
/// σ computed from the model are √40 times too small — the cross-check then finds the AINS and the
/// legacy fit "disagreeing" by 1 mg against a 0.6 mg bound (issue #48 item 7). In a field run below
/// navigation grade with a mean NIS beyond kNisMisfit the covariance is scaled by the mean NIS, as
/// the legacy fit scales its own by the reduced χ². Not on the table (a factory run's large NIS is
/// an unmodelled effect the cross-check and the diagnosis must see) and not at navigation grade.
void scale_sigma_to_innovations(const CalibrationInput& in, AinsResult& out) {
  if (in.setting == Setting::kFactory || in.grade == Grade::kNavigation ||
      !(out.mean_nis > kNisMisfit))
    return;
  out.sigma_scale = std::sqrt(out.mean_nis);
  out.calibration.cov *= out.mean_nis;
  out.calibration.sigma = sigma_from_covariance(out.calibration.cov);
}

/// What the result's reader must know: no convergence, innovations too large, a noise model the
/// filter does not represent.
void add_warnings(const CalibrationInput& in, const AinsOptions& opt, AinsResult& out) {
  CalibrationResult& res = out.calibration;
  if (!res.converged) {
    std::ostringstream os;
    os << "AINS did not converge in " << opt.max_iterations
       << " passes: last update max |dtheta|/sigma = " << out.update_norm_sigma.back();
    res.warnings.push_back(os.str());
  }
  // Each scalar innovation has expectation 1 of ν²/s if the noise model fits; a mean far above
  // it means the data disagree with the model (unmodelled effects, wrong noise spec, bad aiding).
  if (out.mean_nis > kNisMisfit) {
    std::ostringstream os;
    os << "innovations larger than the noise model predicts: mean NIS " << out.mean_nis
       << " (expected <= 1); ";
    if (out.sigma_scale > 1.0)
      os << "sigma scaled by its square root, " << out.sigma_scale
         << " (the data are noisier than the unit's noise model)";
    else
      os << "sigma may be optimistic";
    res.warnings.push_back(os.str());
  }
  // A logger that drops samples now and then would fill the list: the first few, then a count.
  constexpr size_t kListed = 3;
  for (size_t i = 0; i < std::min(in.unusable.size(), kListed); ++i)
    res.warnings.push_back("attitude and velocity released after " +
                           instant_text(in.imu[in.unusable[i].begin].t_s) +
                           " (the next rest decides them): " + in.unusable[i].reason);
  if (in.unusable.size() > kListed)
    res.warnings.push_back("and at " + std::to_string(in.unusable.size() - kListed) +
                           " further clipped or dropped stretches");
  if (in.noise.gyro_bias_instability_radps > 0.0 || in.noise.accel_bias_instability_mps2 > 0.0)
    res.warnings.push_back(
        "noise model has bias instability; AINS models biases as random constants (paper §IV-A)");
}

/// The calibration, and with `smooth` the smoother's navigation output of the last pass.
AinsResult run_ains(const CalibrationInput& in, const AinsOptions& opt, bool smooth) {
  const auto t_start = std::chrono::steady_clock::now();
  const ains::PreparedInput pin = ains::prepare_input(in, opt);
  const bool field = in.setting != Setting::kFactory;

  ains::PassConfig cfg;
  cfg.prior_sigma = effective_prior_sigma(opt, in.unit_prior());
  cfg.prior_mean = ParamVector::Zero();
  cfg.nominal = opt.start ? *opt.start : ParamSet::from_vector(cfg.prior_mean);

  AinsResult out;
  if (field) {
    // Levelling and gyrocompassing on the first rest, from scratch (no reference, no prior).
    out.coarse_C_bn =
        coarse_align(in.imu, pin.first_rest.begin, pin.first_rest.end, ains::alignment_site(in),
                     cfg.nominal, in.noise.vrw_mps_per_sqrt_s,
                     grade_prior(in.grade).alignment_min_window_s)
            .C_bn;
    if (opt.initial_C_bn)
      out.coarse_C_bn = *opt.initial_C_bn;
    else if (in.grade != Grade::kNavigation)
      out.coarse_C_bn = search_initial_heading(pin, opt, cfg, out.coarse_C_bn);
    cfg.C_bn0 = out.coarse_C_bn;
  }
  CalibrationResult& res = out.calibration;
  res.method = "ains";
  res.setting = in.setting;
  std::vector<ains::EpochRecord> epochs;
  const ains::PassResult pass = iterate_passes(pin, opt, smooth, cfg, out, epochs);
  res.params = cfg.nominal;
  res.sigma = sigma_from_covariance(res.cov);
  out.num_updates = pass.num_updates;
  out.mean_nis = pass.nis_count ? pass.nis_sum / static_cast<double>(pass.nis_count) : 0.0;
  if (smooth) {
    out.smoothed = ains::rts_smooth(epochs, &out.smoother_param_mismatch_sigma);
    out.initial_C_bn = out.smoothed.front().nav.C_bn;
  } else if (field) {
    out.initial_C_bn = cfg.C_bn0;  // the last pass's smoothed initial attitude
  }
  if (field) describe_field_frame(res);
  scale_sigma_to_innovations(in, out);
  add_warnings(in, opt, out);
  res.runtime_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  return out;
}

}  // namespace

AinsResult calibrate_ains_detailed(const CalibrationInput& in, const AinsOptions& opt) {
  return run_ains(in, opt, /*smooth=*/true);
}

CalibrationResult calibrate_ains(const CalibrationInput& in, const AinsOptions& opt) {
  // The smoothed navigation states are not part of a calibration: no RTS pass, no epoch records.
  return run_ains(in, opt, /*smooth=*/false).calibration;
}

}  // namespace imucal::calib::ains
