#pragma once
// AINS calibration (paper §IV, ARCHITECTURE §6): a 36-state error-state Kalman filter aided at rest
// by the table orientation (eq. 28-35), zero velocity (eq. 36-39) and mean depth (eq. 40-43), with
// a Rauch-Tung-Striebel smoother over the whole run, run as an *iterated linearised smoother*:
//   1. run the INS with the current parameter estimate as nominal (raw increments compensated by
//      the shared ImuErrorModel), the navigation errors fed back into the nominal at every update
//      (keeps the unstable vertical channel and the attitude linear), parameters fixed in a pass;
//   2. forward KF over the whole run, with the prior on the parameters re-centred on the nominal;
//   3. parameters += filtered parameter error (random constants: smoothed == final filtered);
//   4. repeat until every update is < convergence_sigma_ratio·σ; RTS backward over the last pass
//      gives the smoothed navigation states.
// The state layout and the F/H terms live in ains_model.hpp.
#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "calib/core/calibration_input.hpp"
#include "calib/core/param_set.hpp"
#include "calib/core/strapdown.hpp"

namespace imucal::calib::ains {
using namespace calib::core;

/// Kept for source compatibility: the aiding now follows CalibrationInput::setting.
using AinsSetting = Setting;

/// Aiding by setting (paper §IV-B/C/D; the setting comes from CalibrationInput::setting):
///  * factory: table orientation (eq. 28-35), zero velocity (36-39), mean depth (40-43) at rest;
///    initial attitude from the reference; 36 states;
///  * land: zero velocity and mean depth at rest, no orientation aiding; initial attitude from
///    the data (calib/core/coarse_alignment.hpp; below navigation grade its heading by a
///    likelihood search over 12 headings), refined by the smoother each pass; ς frozen (33
///    states); the common rotation of both triads fixed by the accel-symmetric body frame
///    (calib/core/body_frame.hpp) as three exact pseudo-measurements;
///  * sea: as land, but GNSS horizontal position (eq. 44-47) at every fix and mean depth there,
///    no zero velocity.
struct AinsOptions {
  int max_iterations = 8;                 ///< iterated linearised smoother passes
  double convergence_sigma_ratio = 0.01;  ///< stop when every |Δθ_i| < ratio·σ_i
  double attitude_sigma_rad = 1e-6;       ///< table orientation aiding noise (eq. 28)
  double zupt_sigma_mps = 1e-4;           ///< eq. 36-39
  double depth_sigma_m = 1e-2;            ///< eq. 40-43 (factory, land)
  /// eq. 40-43 at sea: RMS of the unit's heave about mean sea level (calm water: 5 cm amplitude,
  /// as imucal simulate --setting sea). Heave is narrow-band, so treating it as white noise of
  /// this σ is conservative (accel RMS(error/σ) ≈ 0.76 at sea against ≈ 0.9 on land).
  double sea_depth_sigma_m = 0.035;
  double gnss_sigma_m = 0.0;  ///< eq. 44-47; <= 0: each fix's own sigma_m (default 0.3)
  /// Field settings: prior 1-σ of the initial attitude about the coarse alignment. Broad, so the
  /// data (not the alignment, which used the same samples) decide it.
  double initial_tilt_sigma_rad = 1e-2;
  double initial_heading_sigma_rad = 0.1;
  double sea_initial_velocity_sigma_mps = 0.2;  ///< a drifting vessel's speed
  /// Field settings: after a clipped or dropped stretch (CalibrationInput::unusable) the attitude
  /// and velocity it carried are released by this 1-σ (process noise added once): the next rest
  /// levels the unit again, and the stretch's rotation teaches the gyro states nothing — the
  /// filter's way of leaving the move out. A MEMS gyro clipped at 250 °/s for 0.1 s, turning at
  /// 300, loses 5°.
  double unusable_attitude_sigma_rad = 0.15;
  double unusable_velocity_sigma_mps = 1.0;
  double update_interval_s = 1.0;       ///< aiding rate while at rest
  double propagation_interval_s = 1.0;  ///< Φ accumulated over the samples of this interval
  size_t min_rest_samples = 100;        ///< shorter at_rest runs are not used for aiding
  /// 1-σ prior of the sensor states (centred on zero). Elements <= 0 take the built-in default
  /// of the input's grade (prior_sigma_for_grade()).
  ParamSet prior_sigma;
  /// Where the first pass linearises (empty: zero, the nominal unit). A unit far from nominal — a
  /// MEMS gyro 24 % off scale and 3 °/s off zero — is outside the reach of a linearised filter
  /// started at zero; started at the legacy result it converges (issue #21). Only the start: the
  /// prior stays centred on zero with the grade's σ, and the passes iterate to the same fixed
  /// point from any start close enough (tests/calib/ains_grade_test.cpp).
  std::optional<ParamSet> start;
  /// Field settings: the attitude at the INS start in place of the coarse alignment's (which
  /// stays the prior's centre only when this is empty).
  std::optional<Eigen::Matrix3d> initial_C_bn;
};

/// Built-in prior: bias 5 mg / 1 deg/h, dM 5000 ppm (scale and misalignment), ς 1 mrad.
ParamSet default_prior_sigma();
/// The prior of a unit of `grade` before calibration (issue #21: the filter's initial covariance
/// follows the grade): navigation without overrides keeps default_prior_sigma(); otherwise the
/// envelope (calib/core/unit_grade.hpp, with run.toml's [prior] overrides) as 1-σ, ς 1 mrad.
ParamSet prior_sigma_for_grade(const UnitPrior& prior);
/// opt.prior_sigma with non-positive elements replaced by the defaults of `prior`.
ParamSet effective_prior_sigma(const AinsOptions& opt, const UnitPrior& prior = {});

/// Smoothed navigation state at one KF epoch (RTS output), for evaluation and diagnosis.
struct SmoothedNav {
  size_t sample_index = 0;  ///< index into CalibrationInput::imu
  double t_s = 0.0;
  bool aided = false;  ///< an aiding update was applied at this epoch
  NavState nav;        ///< smoothed navigation state (nominal corrected by the smoothed error)
  Eigen::Vector3d psi_rad = Eigen::Vector3d::Zero();  ///< smoothed attitude error of the nominal
  Eigen::Vector3d dv_mps = Eigen::Vector3d::Zero();   ///< smoothed velocity error of the nominal
  Eigen::Vector3d dp_m = Eigen::Vector3d::Zero();     ///< smoothed position error (NED m)
  Eigen::Vector3d sigma_psi_rad = Eigen::Vector3d::Zero();
  Eigen::Vector3d sigma_v_mps = Eigen::Vector3d::Zero();
  Eigen::Vector3d sigma_p_m = Eigen::Vector3d::Zero();
};

/// Everything the AINS produces: the calibration plus the smoother's navigation output and the
/// filter's self-diagnostics.
struct AinsResult {
  CalibrationResult calibration;
  std::vector<SmoothedNav> smoothed;  ///< one per KF epoch of the final pass
  size_t num_updates = 0;             ///< aiding epochs in the final pass
  double mean_nis = 0.0;              ///< mean normalised innovation squared per scalar update
  /// > 1: the σ were scaled by it, √(mean NIS) (field runs below navigation grade whose
  /// innovations exceed the noise model: scale_sigma_to_innovations).
  double sigma_scale = 1.0;
  /// Max over parameters of |smoothed(first epoch) - filtered(last epoch)| / σ: zero for random
  /// constants in exact arithmetic, so a check of the RTS recursion.
  double smoother_param_mismatch_sigma = 0.0;
  std::vector<double> update_norm_sigma;  ///< max_i |Δθ_i|/σ_i of each pass
  /// The smoothed attitude at the INS start (field settings: from the data; factory: the
  /// reference's, corrected by ς̂) and the attitude the passes started from (field only): the
  /// coarse alignment, with its heading searched by likelihood below navigation grade (a gyro
  /// that cannot gyrocompass), or AinsOptions::initial_C_bn.
  Eigen::Matrix3d initial_C_bn = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d coarse_C_bn = Eigen::Matrix3d::Identity();
};

/// Full AINS calibration. Throws std::invalid_argument when the input cannot be calibrated (sizes
/// differ, non-finite values, no rest periods, a sea run without GNSS fixes) and std::runtime_error
/// if the filter diverges numerically.
AinsResult calibrate_ains_detailed(const CalibrationInput& in, const AinsOptions& opt = {});
/// The calibration part of calibrate_ains_detailed (method "ains").
CalibrationResult calibrate_ains(const CalibrationInput& in, const AinsOptions& opt = {});

}  // namespace imucal::calib::ains
