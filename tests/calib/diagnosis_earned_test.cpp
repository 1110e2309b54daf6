// Issue #49: the diagnosis names only what the data support. A K2 run with inner lever arms (and a
// gyro/accelerometer skew) on `short` and factory-std — the cases from another team's
// simulator, rebuilt here with the truth simulator and with tools/altsim (its own scheme and
// generator) — must be explained by the K2 | asymmetry set and the size effect (and the skew),
// each with its size within 3σ of the injected, and nothing else. Before, the K2 set, which the
// sequence cannot tell from asymmetry, was left out of the stepwise search: the run read
// "unexplained" (short) or "explained by bias_instability = 12 × typical" (factory-std).
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "calib/core/calibration_input.hpp"
#include "calib/core/site_presets.hpp"
#include "calib/diagnosis/diagnosis.hpp"
#include "calib/diagnosis/gap_fit.hpp"
#include "calib/nlsq/nlsq.hpp"
#include "calib/sim/sim_input.hpp"
#include "calib/sim/truth_sim.hpp"
#include "sequences/library.hpp"

using namespace imucal;
using namespace imucal::calib;
using namespace imucal::calib::core;
using namespace imucal::calib::diagnosis;
using namespace imucal::calib::effects;
using namespace imucal::calib::sim;

namespace {

/// 10× the catalogue's typical K2 (20, −15, 25 µg/g²): norm 353.6 µg/g².
const Eigen::Vector3d kK2_ug_per_g2(200.0, -150.0, 250.0);

/// Inner lever arms about the triad's centre (their sum is zero): the sizes a sequence resolves
/// whole. A common offset of all three is the whole triad's offset from the rotation centre,
/// which `short` and factory-std leave unresolved (σ ≈ 0.8 m beside K2). Norm sqrt(22) cm.
std::array<Eigen::Vector3d, 3> inner_lever_arms_m() {
  return {Eigen::Vector3d(0.02, 0.01, 0.0), Eigen::Vector3d(-0.01, 0.02, -0.01),
          Eigen::Vector3d(-0.01, -0.03, 0.01)};
}

Effects k2_and_lever_arms(double skew_s) {
  Effects fx;
  fx.accel_k2_per_mps2 = kK2_ug_per_g2 * 1e-6 / kStandardGravity_mps2;
  fx.accel_lever_arm_m = inner_lever_arms_m();
  fx.gyro_accel_skew_s = skew_s;
  return fx;
}

DiagnosisResult diagnose_table_run(const std::string& seq, const Effects& fx, uint64_t seed) {
  UnitModel unit = default_unit();
  unit.effects = fx;
  SimOptions so;
  so.seed = seed;
  const TableGeometry geom;
  const SimResult sim = simulate(sequences::load_profile(seq), geom, demo_factory_site(), unit, so);
  DiagnosisInput in;
  in.cal = input_from_simulation(sim, geom, demo_factory_site(), unit.noise);
  in.geometry = geom;
  return diagnose(in, nlsq::calibrate_nlsq(in.cal).params);
}

const DiagnosisStep* step(const DiagnosisResult& d, const std::string& effect) {
  for (const auto& s : d.steps) {
    if (s.effect == effect) return &s;
    if (std::find(s.set.begin(), s.set.end(), effect) != s.set.end()) return &s;
  }
  return nullptr;
}

void expect_within_3_sigma(const DiagnosisStep* s, double injected, const std::string& what) {
  ASSERT_NE(s, nullptr) << what << " not named";
  EXPECT_LT(std::abs(s->magnitude - injected), 3.0 * s->magnitude_sigma)
      << what << ": " << s->magnitude << " +- " << s->magnitude_sigma << " " << s->unit
      << ", injected " << injected;
}

/// The run names exactly `expected` (a set counts with its members), each size within 3σ.
void expect_named_exactly(const DiagnosisResult& d, std::vector<std::string> expected,
                          double skew_ms, const std::string& what) {
  std::printf("%s: %s\n", what.c_str(), d.summary.c_str());
  for (const auto& u : d.unsupported)
    std::printf("  fitted, not supported: %s = %.3g +- %.3g %s (%s)\n", u.effect.c_str(),
                u.magnitude, u.magnitude_sigma, u.unit.c_str(), u.reason.c_str());
  EXPECT_EQ(d.verdict, "explained") << what;
  std::vector<std::string> named = d.explained_by;
  std::sort(named.begin(), named.end());
  std::sort(expected.begin(), expected.end());
  EXPECT_EQ(named, expected) << what << ": " << d.summary;
  // K2 · f² = Kap · |f| · g at 0 and ±1 g: the set's size reads the same number in µg/g² or ppm.
  expect_within_3_sigma(step(d, "accel_quadratic_k2"), kK2_ug_per_g2.norm(), what + " K2 set");
  double arms_mm = 0.0;
  for (const auto& r : inner_lever_arms_m()) arms_mm += r.squaredNorm() * 1e6;
  expect_within_3_sigma(step(d, "size_effect"), std::sqrt(arms_mm), what + " lever arms");
  if (skew_ms > 0.0) expect_within_3_sigma(step(d, "gyro_accel_skew"), skew_ms, what + " skew");
  const DiagnosisStep* k2 = step(d, "accel_quadratic_k2");
  if (k2) {
    EXPECT_FALSE(k2->set.empty()) << what << ": K2 is named as its set";
  }
}

}  // namespace

TEST(DiagnosisEarned, K2AndInnerLeverArmsAreNamedAsTheK2SetAndTheSizeEffect) {
  for (const std::string seq : {"short", "factory-std"})
    expect_named_exactly(diagnose_table_run(seq, k2_and_lever_arms(0.0), 5),
                         {"accel_quadratic_k2", "accel_asymmetry", "size_effect"}, 0.0, seq);
}

TEST(DiagnosisEarned, WithAOneMillisecondSkewTheSkewIsNamedToo) {
  for (const std::string seq : {"short", "factory-std"})
    expect_named_exactly(
        diagnose_table_run(seq, k2_and_lever_arms(1e-3), 7),
        {"accel_quadratic_k2", "accel_asymmetry", "size_effect", "gyro_accel_skew"}, 1.0, seq);
}

// The lever arms' common part (the catalogue's typical pattern has one of 29 mm) is the triad's
// offset from the rotation centre: unresolved beside K2, it is left out of the size, which is
// then the inner arms' (33.7 mm of the pattern's 44.7 mm), and the step says so.
TEST(DiagnosisEarned, TheUnresolvedCommonPartOfTheLeverArmsIsLeftOutOfTheirSize) {
  Effects fx = k2_and_lever_arms(0.0);
  fx.accel_lever_arm_m = {Eigen::Vector3d(0.02, 0.01, 0.0), Eigen::Vector3d(-0.01, 0.02, 0.0),
                          Eigen::Vector3d(0.0, 0.01, 0.03)};
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& r : fx.accel_lever_arm_m) mean += r / 3.0;
  double inner_mm2 = 0.0;
  for (const auto& r : fx.accel_lever_arm_m) inner_mm2 += (r - mean).squaredNorm() * 1e6;
  const DiagnosisResult d = diagnose_table_run("short", fx, 5);
  std::printf("%s\n", d.summary.c_str());
  const DiagnosisStep* s = step(d, "size_effect");
  ASSERT_NE(s, nullptr) << d.summary;
  std::printf("size_effect %.3g +- %.3g mm (inner part %.3g mm); note: %s\n", s->magnitude,
              s->magnitude_sigma, std::sqrt(inner_mm2), s->note.c_str());
  EXPECT_LT(std::abs(s->magnitude - std::sqrt(inner_mm2)), 3.0 * s->magnitude_sigma + 1.0);
  EXPECT_NE(s->note.find("not resolved"), std::string::npos) << s->note;
}

// The plausible sizes per grade (issue #49 item 1): bounded where physics bounds them whatever the
// grade (a lever arm at most the unit's size, a skew a few sample periods), never smaller for a
// lower grade, and a navigation unit's bias instability held to its datasheet's range.
TEST(DiagnosisEarned, PlausibleSizesGrowWithTheGradeAndStopAtPhysicalBounds) {
  for (const EffectInfo& e : effect_catalogue()) {
    const double nav = plausible_limit_typical(e.id, Grade::kNavigation, 50.0);
    const double tac = plausible_limit_typical(e.id, Grade::kTactical, 50.0);
    const double mems = plausible_limit_typical(e.id, Grade::kMems, 50.0);
    EXPECT_LE(nav, tac) << e.name;
    EXPECT_LE(tac, mems) << e.name;
  }
  const double lever_typical_mm = 44.72;
  EXPECT_LT(plausible_limit_typical(EffectId::kSizeEffect, Grade::kMems, 50.0) * lever_typical_mm,
            301.0);
  EXPECT_LE(plausible_limit_typical(EffectId::kGyroAccelSkew, Grade::kMems, 50.0) * 0.5, 50.0);
  EXPECT_LE(plausible_limit_typical(EffectId::kBiasInstability, Grade::kNavigation, 50.0), 10.0);
}

// A drift is no output filter (issue #49: on both independent simulators the output filter was
// named beside every Gauss-Markov drift, lag-1 a ≈ 0.04). A bias wandering over minutes raises the
// rest samples' lag-1 autocorrelation; a filter's falls from lag 1 to lag 2, the drift's does not.
// factory-std, a navigation unit whose biases wander at 8× the typical (80 µg, 0.008 °/h, τ 500
// s, within its grade's range): the filter is not named; where it is significant on lag 1 it is
// listed as fitted, not supported, saying why.
const DiagnosisStep* named(const DiagnosisResult& d, const std::string& effect) {
  for (const auto& s : d.steps)
    if (s.effect == effect) return &s;
  return nullptr;
}

Effects wandering_biases() {
  Effects fx;
  fx.instability_accel_mps2 = 80e-6 * kStandardGravity_mps2;
  fx.instability_gyro_radps = 0.008 * kDegToRad / 3600.0;
  fx.instability_tau_s = 500.0;
  return fx;
}

TEST(DiagnosisEarned, ADriftIsNoOutputFilter) {
  for (uint64_t seed : {21u, 22u}) {
    const DiagnosisResult d = diagnose_table_run("factory-std", wandering_biases(), seed);
    std::printf("seed %llu: %s\n", static_cast<unsigned long long>(seed), d.summary.c_str());
    EXPECT_EQ(named(d, "output_filter"), nullptr) << d.summary;
    for (const auto& u : d.unsupported) {
      if (u.effect == "output_filter") {
        EXPECT_NE(u.reason.find("lag 2"), std::string::npos) << u.reason;
      }
    }
  }
}

// The converse: a real filter (a = 0.2 on both sensors, the catalogue's typical) beside the same
// drift is still named — it makes lag 1 and lag 2 differ.
TEST(DiagnosisEarned, AFilterBesideADriftIsStillNamed) {
  Effects fx = wandering_biases();
  fx.output_filter_gyro = 0.2;
  fx.output_filter_accel = 0.2;
  const DiagnosisResult d = diagnose_table_run("factory-std", fx, 23);
  std::printf("%s\n", d.summary.c_str());
  EXPECT_NE(named(d, "output_filter"), nullptr) << d.summary;
}

// The drift alone, with a size that owns up to τ (issue #49 item 3: bias instability judged against
// the grade's range). The run cannot tell τ 500 s from 3000 s (the likelihood is flat within 2
// over them) while σ doubles between them; judged on the larger σ alone, the drift read 19.5 ± 1.2
// × typical, "implausible" beside a navigation unit's 10×, and thermal drift, lever arms, K2,
// asymmetry, table wobble and a skew were named for it. Its size: 8× typical (the RMS of the gyro
// and accelerometer ratios), within 3σ of what is named.
TEST(DiagnosisEarned, ANavigationUnitsDriftWithinItsRangeIsNamedAloneWithAnHonestSize) {
  for (uint64_t seed : {21u, 22u}) {
    const DiagnosisResult d = diagnose_table_run("factory-std", wandering_biases(), seed);
    std::printf("seed %llu: %s\n", static_cast<unsigned long long>(seed), d.summary.c_str());
    ASSERT_EQ(d.steps.size(), 1u) << d.summary;
    EXPECT_EQ(d.steps[0].effect, "bias_instability") << d.summary;
    EXPECT_LT(std::abs(d.steps[0].magnitude - 8.0), 3.0 * d.steps[0].magnitude_sigma) << d.summary;
  }
}

// Where the simulators' runs meet the sequence's resolution (issue #49 item 5): a navigation unit's
// gyro drift alone, at its grade's bound (10× typical, 0.01 °/h), moves factory-std's ~90 s rest
// means by about the ARW's own scatter there (0.0015 °/√h over 90 s: 0.0095 °/h), so the run
// stays within a few σ of the model and nothing is named — on gnss-ins-sim's gyro-only runs at
// 3–10× as here. What must hold: nothing else is named for it.
TEST(DiagnosisEarned, AGyroDriftAtTheNavigationBoundNamesNothingElse) {
  Effects fx;
  fx.instability_gyro_radps = 0.01 * kDegToRad / 3600.0;
  for (double tau_s : {300.0, 1000.0}) {
    fx.instability_tau_s = tau_s;
    for (uint64_t seed : {31u, 33u}) {
      const DiagnosisResult d = diagnose_table_run("factory-std", fx, seed);
      std::printf("tau %g s, seed %llu: %s\n", tau_s, static_cast<unsigned long long>(seed),
                  d.summary.c_str());
      for (const auto& s : d.steps) EXPECT_EQ(s.effect, "bias_instability") << d.summary;
    }
  }
}
