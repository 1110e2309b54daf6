// Land AINS below navigation grade when the data are noisier than the unit's noise model says
// (issue #48 item 7): a real MEMS unit's rests carry tremor and its output filter's coloured noise,
// and its innovations run at a mean NIS of 40 (the corpus' MPU-9150 units). The filter's σ, computed
// from the model, are then too small by about √NIS; the result scales them by it, as the legacy fit
// scales by its reduced χ², and says so. Simulated here by telling the filter a noise model five
// times quieter than the unit's.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "calib/ains/ains.hpp"
#include "calib/core/body_frame.hpp"
#include "calib/legacy/legacy.hpp"
#include "tests/support/mems_runs.hpp"

namespace imucal::calib {
using namespace imucal::calib::core;
using namespace imucal::calib::sim;
namespace {

struct Honesty {
  double rms_error_over_sigma = 0.0;  ///< over the 24 sensor parameters
  double sigma_scale = 1.0;
  double mean_nis = 0.0;
};

Honesty ains_honesty(const FieldSimResult& sim, double noise_told_factor) {
  CalibrationInput in = testing::mems_input(sim);
  in.noise.arw_rad_per_sqrt_s *= noise_told_factor;
  in.noise.vrw_mps_per_sqrt_s *= noise_told_factor;
  ains::AinsOptions o;
  o.start = legacy::calibrate_legacy(in).params;
  const ains::AinsResult r = ains::calibrate_ains_detailed(in, o);
  const ParamVector truth = to_accel_symmetric_frame(sim.truth).params.to_vector();
  const ParamVector est = r.calibration.params.to_vector(), sig = r.calibration.sigma.to_vector();
  double ss = 0.0;
  for (int i = 0; i < 24; ++i) ss += std::pow((est(i) - truth(i)) / sig(i), 2);
  return {std::sqrt(ss / 24.0), r.sigma_scale, r.mean_nis};
}

TEST(AinsNoiseMisfit, DataNoisierThanTheModelScaleTheSigmaByTheInnovations) {
  for (uint64_t seed : {31u, 32u}) {
    const FieldSimResult sim = testing::simulate_mems(seed);
    const Honesty told_right = ains_honesty(sim, 1.0);
    const Honesty told_quiet = ains_honesty(sim, 0.2);
    std::printf(
        "seed %llu: noise model right: mean NIS %.2f, scale %.2f, RMS(error/σ) %.2f; told 5× "
        "quieter: mean NIS %.1f, scale %.2f, RMS(error/σ) %.2f (%.2f unscaled)\n",
        static_cast<unsigned long long>(seed), told_right.mean_nis, told_right.sigma_scale,
        told_right.rms_error_over_sigma, told_quiet.mean_nis, told_quiet.sigma_scale,
        told_quiet.rms_error_over_sigma, told_quiet.rms_error_over_sigma * told_quiet.sigma_scale);
    EXPECT_EQ(told_right.sigma_scale, 1.0) << "a model that fits is left alone";
    EXPECT_GT(told_quiet.sigma_scale, 3.0);
    EXPECT_LT(told_quiet.rms_error_over_sigma, 2.0 * told_right.rms_error_over_sigma + 0.5);
    EXPECT_GT(told_quiet.rms_error_over_sigma * told_quiet.sigma_scale,
              3.0 * told_right.rms_error_over_sigma)
        << "unscaled, the σ of the misfit model must be overconfident";
  }
}

}  // namespace
}  // namespace imucal::calib
