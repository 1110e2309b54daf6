#pragma once
// Truth simulator for field runs (issue #9, paper §IV-C/D): a unit turned by hand through the
// rest positions of a sequence, on land (the ground still) or at sea (a DP vessel that drifts
// and rocks), with no table or attitude log and, at sea, simulated GNSS fixes.
//
// The trajectory:
//  * attitude  C_bn(t) = C_rock(t) · E(t) · C_seq(τ(t)): the sequence's table attitude (default
//    geometry, a random heading) at a time-warped clock τ — every rest and move lasts its sequence
//    duration times U(1 - jitter, 1 + jitter) — times a placement error E: a random rotation
//    (placement_sigma_deg per axis) drawn per rest and blended smoothly during each move, and at
//    sea a rocking C_rock = exp([ρ(t) ×]) of roll/pitch/yaw sinusoids;
//  * position  the site, plus at sea a horizontal DP drift (sinusoids, drift_amplitude_m,
//    drift_period_s) and heave (heave_amplitude_m, heave_period_s), NED metres;
//  * increments exact to the physics in the Earth-centred inertial frame: dθ from the attitudes
//    w.r.t. inertial space at the sample ends, dv = C_bi(t0)ᵀ [Δv_i − ∫ G_i dt] (inertial velocity
//    change minus gravitation, Gauss–Legendre), so translation, transport rate and Earth rate are
//    all in; then the unit's error model, sensor effects and noise (TruthSensor).
// rest_tremor (calib/effects/rest_tremor.hpp, land only): the hand that placed the unit holds it
// in each rest, turning it by its tremor and sway about its pivot — attitude and position move
// together, so gyros and accelerometers sense one motion through the physics above.
// The size effect (the accelerometers' lever arms) acts on the hand's rotations as on the table's;
// latitude_error puts the unit at the true latitude while the site keeps the configured one (the
// GNSS fixes report the true position). Table effects (non-orthogonality, wobble, time offset)
// have no meaning here and are refused; gravity_error is the true local gravity's departure from
// the site's (normal or surveyed) value. The site's position is the tangent-frame origin; at sea
// the GNSS fixes are the platform's true position plus white noise.
#include <cstdint>
#include <utility>
#include <vector>

#include "calib/core/calibration_input.hpp"
#include "calib/core/earth.hpp"
#include "calib/core/imu_increment.hpp"
#include "calib/sim/truth_sim.hpp"
#include "sequences/motion_profile.hpp"

namespace imucal::calib::sim {
using namespace calib::core;
using namespace calib::effects;

struct FieldSimOptions {
  Setting setting = Setting::kLand;  ///< kLand or kSea (kFactory is refused: use simulate())
  double rate_hz = 100.0;
  uint64_t seed = 1;
  bool noise = true;
  double placement_sigma_deg = 2.0;  ///< hand placement error per axis, per rest
  double duration_jitter = 0.2;      ///< rest and move durations × U(1 − j, 1 + j)
  // Sea only.
  double rock_amplitude_deg = 0.05;  ///< roll/pitch amplitude (yaw: half of it)
  double rock_period_s = 8.0;
  double drift_amplitude_m = 2.0;  ///< horizontal DP excursion
  double drift_period_s = 300.0;
  double heave_amplitude_m = 0.05;
  double heave_period_s = 7.0;
  double gnss_rate_hz = 1.0;
  double gnss_sigma_m = 0.3;  ///< white, per horizontal axis (the paper's 30 cm)
};

struct FieldSimResult {
  ImuSeries imu;
  std::vector<bool> true_rest;  ///< per sample: the hand is not turning the unit
  std::vector<GnssFix> gnss;    ///< sea only
  ParamSet truth;               ///< the unit's parameters (housing frame; ς = 0)
  /// True attitude at every sample (for tests of the alignment and of the filter's navigation).
  std::vector<Eigen::Matrix3d> C_bn;
  /// The rest spans [t0, t1] of the hand's timeline (truth.json "rest_intervals").
  std::vector<std::pair<double, double>> rest_spans;
};

/// Throws std::invalid_argument for a factory setting, a table effect, rest_tremor at sea, or
/// options out of range.
FieldSimResult simulate_field(const sequences::MotionProfile& profile, const Site& site,
                              const UnitModel& unit, const FieldSimOptions& options);

}  // namespace imucal::calib::sim
