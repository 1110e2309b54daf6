// The output_filter effect (ARCHITECTURE §7, calib/effects/output_filter.hpp; issue #48 item 8): a
// sensor that low-pass filters its output, y_k = a y_{k-1} + (1-a) x_k. Expectations come from the
// AR(1) process the filter makes of white noise (lag-1 autocorrelation a, sample variance
// (1-a)/(1+a) of the input's, DC gain 1) and from the truth simulator's injected coefficient; the
// diagnosis must name it with a within 3σ of the truth, stay silent on null runs, and tell it from
// quantisation, which moves the same lag-1 statistic the other way.
#include "calib/effects/output_filter.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <string>

#include "calib/core/calibration_input.hpp"
#include "calib/core/site_presets.hpp"
#include "calib/diagnosis/diagnosis.hpp"
#include "calib/nlsq/nlsq.hpp"
#include "calib/sim/sim_input.hpp"
#include "calib/sim/truth_sim.hpp"
#include "sequences/library.hpp"
#include "tests/support/diagnosis_finding.hpp"

using namespace imucal;
using namespace imucal::calib;
using namespace imucal::calib::core;
using namespace imucal::calib::diagnosis;
using namespace imucal::calib::effects;
using namespace imucal::calib::nlsq;
using namespace imucal::calib::sim;

namespace {

const sequences::MotionProfile& factory_std_profile() {
  static const sequences::MotionProfile p = sequences::load_profile("factory-std");
  return p;
}

/// factory-std on the default unit with `fx` injected and withheld from the diagnoser (which keeps
/// the default unit's declared noise), diagnosed against its own NLSQ calibration.
DiagnosisResult diagnose_filtered_run(const Effects& fx, uint64_t seed) {
  UnitModel unit = default_unit();
  unit.effects = fx;
  SimOptions so;
  so.noise = true;
  so.seed = seed;
  const TableGeometry geom;
  const SimResult sim = simulate(factory_std_profile(), geom, demo_factory_site(), unit, so);
  DiagnosisInput in;
  in.cal = input_from_simulation(sim, geom, demo_factory_site(), default_unit().noise);
  in.geometry = geom;
  return diagnose(in, calibrate_nlsq(in.cal).params);
}

using test_support::candidate;
using test_support::named;

void print_filter(const char* what, const DiagnosisResult& d) {
  const CandidateResult& f = candidate(d, "output_filter");
  const CandidateResult& q = candidate(d, "quantisation");
  std::printf(
      "%s: verdict %s, chi2/dof %.3f; output_filter lr %.1f p %.2g gyro_a %.4f +- %.4f accel_a "
      "%.4f +- %.4f held-out %.2f -> %.2f; quantisation lr %.1f; steps:",
      what, d.verdict.c_str(), d.overall_gap, f.lr, f.p_value, f.params[0].value, f.params[0].sigma,
      f.params[1].value, f.params[1].sigma, f.held_out_gap_before, f.held_out_gap, q.lr);
  for (const auto& s : d.steps) std::printf(" %s", s.effect.c_str());
  std::printf("\n");
}

}  // namespace

// The forward model against the AR(1) theory: on white input the output's lag-1 autocorrelation
// is a, its variance (1-a)/(1+a) of the input's, and a long sum of outputs is the sum of inputs
// (DC gain 1: a mean keeps the input's variance).
TEST(OutputFilter, WhiteNoiseThroughTheFilterIsAnAr1OfCoefficientA) {
  for (double a : {0.3, 0.6, 0.9}) {
    OutputFilter f{a};
    std::mt19937_64 rng(7);
    std::normal_distribution<double> n01;
    const int n = 400000;
    double sx = 0.0, sy = 0.0, s0 = 0.0, s1 = 0.0, prev = 0.0, sxx = 0.0;
    for (int k = 0; k < n; ++k) {
      const Vec3<double> x(n01(rng), 0.0, 0.0);
      const double y = f.apply(x)(0);
      sx += x(0);
      sy += y;
      sxx += x(0) * x(0);
      s0 += y * y;
      if (k > 0) s1 += y * prev;
      prev = y;
    }
    EXPECT_NEAR(s1 / s0, a, 0.01) << a;
    EXPECT_NEAR((s0 / n) / (sxx / n), (1.0 - a) / (1.0 + a), 0.02) << a;
    // The sums differ only by the filter's last state's lag (a/(1-a) samples of O(1) noise).
    EXPECT_LT(std::abs(sy - sx), 10.0 * a / (1.0 - a)) << a;
    EXPECT_NEAR(output_filter_coefficient(output_filter_corner_hz(a, 0.01), 0.01), a, 1e-12);
  }
}

// Filtered units on factory-std (gyro and accelerometer coefficients between 0.5 and 0.9, equal or
// not): the diagnosis names output_filter in every run with each coefficient within 3σ of the
// truth, its held-out lag-1 gap shrinks by more than half its excess, and quantisation (the other
// lag-1 effect) is not named. Unequal coefficients delay the gyros and accelerometers by different
// a/(1-a) samples, which is a gyro-accelerometer skew: that the diagnosis names it too is right.
TEST(OutputFilter, DiagnosisNamesAFilteredOutputWithItsCoefficient) {
  const struct {
    double gyro_a, accel_a;
    uint64_t seed;
  } runs[] = {{0.7, 0.5, 41}, {0.5, 0.9, 42}, {0.9, 0.6, 43}, {0.6, 0.6, 44}};
  for (const auto& run : runs) {
    Effects fx;
    fx.output_filter_gyro = run.gyro_a;
    fx.output_filter_accel = run.accel_a;
    const DiagnosisResult d = diagnose_filtered_run(fx, run.seed);
    print_filter(("filtered seed " + std::to_string(run.seed)).c_str(), d);
    test_support::expect_per_sample_finding(d, "output_filter", run.gyro_a, run.accel_a, 3.0,
                                            "seed " + std::to_string(run.seed));
    EXPECT_FALSE(candidate(d, "quantisation").significant) << run.seed;
    EXPECT_FALSE(named(d, "quantisation")) << run.seed;
  }
}

// Null runs (no effect): output_filter is never named (its one-sided test at the diagnosis'
// Bonferroni level, 10⁻³ / 15 per candidate: expected false alarms over 10 runs ~ 10⁻³).
TEST(OutputFilter, NullRunsDoNotNameIt) {
  for (uint64_t seed = 51; seed <= 60; ++seed) {
    const DiagnosisResult d = diagnose_filtered_run(Effects{}, seed);
    print_filter(("null seed " + std::to_string(seed)).c_str(), d);
    EXPECT_FALSE(candidate(d, "output_filter").significant) << seed;
    EXPECT_FALSE(named(d, "output_filter")) << seed;
  }
}

// Quantisation alone (registers 20x coarser than declared: the lag-1 autocovariance -LSB²/12
// pulls the rest samples' correlation negative): quantisation is named, the output filter (which
// would pull it positive) is not. The two act on the same statistic with opposite signs.
TEST(OutputFilter, QuantisationAloneIsToldApartFromAFilter) {
  Effects fx;
  fx.quant_dtheta_rad = 1e-7;
  fx.quant_dv_mps = 2e-5;
  const DiagnosisResult d = diagnose_filtered_run(fx, 21);
  print_filter("quantised", d);
  EXPECT_TRUE(named(d, "quantisation")) << d.summary;
  EXPECT_FALSE(candidate(d, "output_filter").significant);
  EXPECT_FALSE(named(d, "output_filter"));
}
