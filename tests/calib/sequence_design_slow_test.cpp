// Issue #23 "What it must show": `design-sequence` at factory-std's own time designs a sequence no
// group of which is worse than factory-std's (within 2 %, parameter by parameter), keeping every
// effect factory-std separates within 1.5x its detection threshold; and the inverse question on
// short. The designer starts from
// factory-std itself and takes only better tours, so this holds it to not trading one group
// against another beyond the tolerance. A few minutes (the full search with the effects).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>

#include "calib/core/site_presets.hpp"
#include "calib/diagnosis/false_alarm.hpp"
#include "calib/sim/sim_input.hpp"
#include "calib/studies/design/sequence_design.hpp"
#include "sequences/library.hpp"
#include "sequences/parser.hpp"
#include "sequences/profile_generator.hpp"
#include "tests/support/ci_count.hpp"

namespace imucal::calib {
using namespace imucal::calib::core;
using namespace imucal::calib::diagnosis;
using namespace imucal::calib::effects;
using namespace imucal::calib::sim;
using namespace imucal::calib::studies::design;
namespace {

/// The rate of the target search's CRLB runs: the product's 20 Hz at the whole count
/// (IMUCAL_WHOLE_COUNTS=1), 10 Hz in ctest (a run costs ∝ rate: 111 s on a busy machine against
/// 196 s in the last ctest run). The final figures the test asserts on stay at 100 Hz, so a search
/// misled by its rate still fails it. IMUCAL_DESIGN_SEARCH_RATE_HZ overrides.
double search_rate_hz() {
  const char* env = std::getenv("IMUCAL_DESIGN_SEARCH_RATE_HZ");
  if (env && std::atof(env) > 0) return std::atof(env);
  return test_support::whole_counts() ? 20.0 : 10.0;
}

TEST(SequenceDesignAtItsOwnTime, NoGroupWorseThanFactoryStd) {
  const sequences::Sequence reference =
      sequences::parse_sequence_file(sequences::resolve_sequence("factory-std"));
  const UnitModel unit = default_unit();
  DesignSetting s;
  s.site = demo_factory_site();
  s.noise = unit.noise;
  s.base = unit.params;
  s.limits = sequences::effective_limits(sequences::TableLimits{}, reference.limits);
  s.diagnosis = diagnosis_options_for_false_alarm(kDefaultGapFalseAlarm);
  s.exact_run = [&](const sequences::MotionProfile& p, double rate_hz) {
    return truth_run_source(p, s.geometry, s.site, unit, rate_hz)(Effects{}, 1, false);
  };
  const double t_s = sequences::generate_profile(reference).duration_s();
  const SequenceDesign d = design_for_time(reference, t_s, s);
  EXPECT_NEAR(d.design.duration_s, t_s, 0.11);
  for (int i = 0; i < ParamSet::kSize; ++i) {
    const double r = d.design.sigma(i) / d.reference.sigma(i);
    std::printf("%-26s sigma design/factory-std %.4f\n", param_info(i).name.c_str(), r);
    EXPECT_LE(r, 1.02) << param_info(i).name;
  }
  const auto lost = effects_lost(d.reference.effects, d.design.effects, 1.5);
  EXPECT_TRUE(lost.empty()) << lost.front();
  std::printf("objective %.4f after %d CRLB runs\n", d.objective, d.evaluations);
}

// The inverse question (--target-from SEQ --factor K): the least time with every σ ≤ K × SEQ's.
// On short with K = 1.2 (effects not analysed, to keep it short): a design shorter than short,
// every parameter within 1.2× short's, and no time under the floor bound T ≥ (N/Kσ)². The search
// at 10 Hz in ctest, 20 Hz at the whole count (search_rate_hz above): the same bisection, the
// same bounds; a 10 Hz search found 366 s (0.708 of short) with every bound held.
TEST(SequenceDesignForATarget, FindsAShorterSequenceWithinTheFactorOfShort) {
  const sequences::Sequence s_seq =
      sequences::parse_sequence_file(sequences::resolve_sequence("short"));
  DesignSetting s;
  s.site = demo_factory_site();
  s.limits = sequences::effective_limits(sequences::TableLimits{}, s_seq.limits);
  s.search_rate_hz = search_rate_hz();
  const SequenceDesign d = design_for_target(s_seq, s_seq, 1.2, s);
  const double t_short_s = sequences::generate_profile(s_seq).duration_s();
  std::printf("short %.0f s; sigma <= 1.2 x short's in %.0f s (%.3f of it)\n", t_short_s,
              d.design.duration_s, d.design.duration_s / t_short_s);
  EXPECT_LT(d.design.duration_s, t_short_s);
  EXPECT_LE(d.objective, 1.0);
  for (int i = 0; i < ParamSet::kSize; ++i) {
    // The search judged at its rate (10 or 20 Hz), the figures at 100 Hz: equal to 0.1 %.
    EXPECT_LE(d.design.sigma(i), 1.2 * 1.001 * d.reference.sigma(i)) << param_info(i).name;
    const double floor = white_noise_floor(i, s.noise, 1.0);
    if (floor > 0) {
      EXPECT_GE(d.design.duration_s, std::pow(floor / (1.2 * d.reference.sigma(i)), 2));
    }
  }
}

}  // namespace
}  // namespace imucal::calib
