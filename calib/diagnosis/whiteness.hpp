#pragma once
// The "over time" part of localising a gap (ARCHITECTURE §8): per-sample statistics of the rest
// samples (each rest's mean removed) against what the declared noise predicts — whiteness (lag-1
// autocorrelation, which quantisation with a carried remainder makes negative) and the Allan
// deviation of the rate residual at τ = 1, 10, 100, 1000 samples (white noise falls as 1/√τ, a bias
// instability flattens it, quantisation steepens it to 1/τ at short τ).
#include <array>
#include <vector>

#include "calib/core/calibration_input.hpp"

namespace imucal::calib::diagnosis {
using namespace calib::core;

/// Per-sample statistics of the rest residuals per sensor axis (the "over time" part of localising
/// the gap): lag-1 autocorrelation with its z against the declared noise, and the Allan deviation
/// of the rate residual against the declared white noise.
struct WhitenessStats {
  std::array<double, 6> lag1_autocorr{};    ///< accel x..z, gyro x..z
  std::array<double, 6> lag1_z{};           ///< departure from the declared quantisation, in σ
  std::vector<double> tau_s;                ///< Allan τ
  std::array<std::vector<double>, 6> adev;  ///< measured (m/s² or rad/s)
  std::array<std::vector<double>, 6> adev_expected;  ///< declared white noise + quantisation
};

WhitenessStats whiteness_stats(const CalibrationInput& in, const std::vector<RestPeriod>& rests);

}  // namespace imucal::calib::diagnosis
