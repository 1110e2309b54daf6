#pragma once
// A unit's stochastic model: what the truth simulator draws its noise from and what the
// estimators weight their observations with (a datasheet or the unit file, ARCHITECTURE §3). Shared
// by both sides, so it lives with the conventions rather than in either.
#include <optional>
#include <string_view>

#include "calib/core/conventions.hpp"

namespace imucal::calib::core {

/// How a sample's increment was rounded to its LSB (issue #50). The two leave different
/// statistics, and the diagnosis tells effects apart by them:
///  * kCarried: an accumulating output register (the station's protocol, an increment-output
///    unit) rounds each increment and carries the remainder into the next, so the error is
///    e_k - e_{k-1}, e uniform on ±LSB/2: variance LSB²/6 a sample, lag-1 autocovariance
///    -LSB²/12, and a sum of any number of increments off by two residues (2·LSB²/12).
///  * kPerSample: a logger of counts rounds each rate sample on its own (the increment's LSB is
///    scale × dt): white error, variance LSB²/12 a sample, no lag-1 autocovariance, and a sum of
///    n increments off by n·LSB²/12 — a random walk like ARW's.
enum class LsbRounding { kCarried, kPerSample };

/// Stochastic model of a unit (SI units; see unit-file parsing for human units).
struct NoiseModel {
  double arw_rad_per_sqrt_s = 0.0015 * kDegToRad / 60.0;  ///< angle random walk (0.0015 deg/√h)
  double vrw_mps_per_sqrt_s = 10.0 * kMicroG_mps2;        ///< velocity random walk (10 µg/√Hz)
  double gyro_bias_instability_radps = 0.0;               ///< Gauss-Markov σ
  double gyro_bias_tau_s = 1000.0;
  double accel_bias_instability_mps2 = 0.0;
  double accel_bias_tau_s = 1000.0;
  double dtheta_lsb_rad = 1e-9;  ///< quantisation of the output (0 = off)
  double dv_lsb_mps = 1e-7;
  LsbRounding lsb_rounding = LsbRounding::kCarried;  ///< how both LSBs were rounded
};

/// Variance of one sample's rounding error (one axis).
inline double rounding_variance(double lsb, LsbRounding r) {
  return lsb * lsb / (r == LsbRounding::kCarried ? 6.0 : 12.0);
}

/// Lag-1 autocovariance of the rounding error between neighbouring samples (one axis).
inline double rounding_lag1_autocov(double lsb, LsbRounding r) {
  return r == LsbRounding::kCarried ? -lsb * lsb / 12.0 : 0.0;
}

/// The rounding's share of a sum of increments, in the two terms the estimators add up:
///  * rounding_white_density: per-sample rounding is white noise of this density (unit²/s, like
///    ARW² and VRW²) at the nominal sample period dt_s — a sum over T has variance n·LSB²/12 =
///    LSB²/(12 dt)·T; carried rounding has none (0);
///  * rounding_end_residues: carried rounding leaves one residue at each end of any sum
///    (2·LSB²/12, whatever its length); per-sample rounding has none (0).
inline double rounding_white_density(double lsb, LsbRounding r, double dt_s) {
  return r == LsbRounding::kPerSample && dt_s > 0.0 ? lsb * lsb / (12.0 * dt_s) : 0.0;
}
inline double rounding_end_residues(double lsb, LsbRounding r) {
  return r == LsbRounding::kCarried ? 2.0 * lsb * lsb / 12.0 : 0.0;
}

/// run.toml's spelling of the rounding ([noise] lsb_rounding).
inline const char* lsb_rounding_name(LsbRounding r) {
  return r == LsbRounding::kCarried ? "carried" : "per_sample";
}
inline std::optional<LsbRounding> parse_lsb_rounding(std::string_view s) {
  if (s == "carried") return LsbRounding::kCarried;
  if (s == "per_sample") return LsbRounding::kPerSample;
  return std::nullopt;
}

}  // namespace imucal::calib::core
