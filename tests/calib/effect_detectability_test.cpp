// Detection thresholds and separability of the effects catalogue per sequence (issue #8 item 3).
// Expectations from physics: gravity error is a common accelerometer scale factor on any table
// (only gravity as reference); K2·f² and Kap·|f| coincide at 0 and ±1 g; a table-time offset has no
// signature when encoder angles are used only at rest; a short run cannot tell a warm-up from a
// bias, a longer one (factory-std) can.
#include "calib/diagnosis/effect_detectability.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <map>

#include "calib/core/site_presets.hpp"
#include "calib/sim/sim_input.hpp"
#include "sequences/library.hpp"

using namespace imucal;
using namespace imucal::calib;
using namespace imucal::calib::core;
using namespace imucal::calib::diagnosis;
using namespace imucal::calib::effects;
using namespace imucal::calib::sim;

namespace {

std::map<std::string, EffectDetectability> analyse(const std::string& seq) {
  const UnitModel unit = default_unit();
  const RunSource world = truth_run_source(sequences::load_profile(seq), TableGeometry{},
                                           demo_factory_site(), unit, 100.0);
  const auto d =
      effect_detectability(world(Effects{}, 1, /*noise=*/false), TableGeometry{}, unit.params);
  std::map<std::string, EffectDetectability> m;
  for (const auto& e : d) m[e.name] = e;
  EXPECT_EQ(d.size(), effect_catalogue().size());
  return m;
}

}  // namespace

TEST(EffectDetectability, FactoryStdSeparatesTheDynamicAndTableEffectsAndNamesWhatItCannot) {
  const auto m = analyse("factory-std");
  for (const char* name : {"size_effect", "gyro_g_sensitivity", "gyro_accel_skew", "thermal_drift",
                           "table_nonorthogonality", "table_wobble", "latitude_error"}) {
    const auto& e = m.at(name);
    EXPECT_TRUE(e.separable()) << name << ": " << e.reason;
    EXPECT_TRUE(std::isfinite(e.threshold) && e.threshold > 0.0) << name;
  }
  // Gravity error: every accelerometer scale factor absorbs it.
  const auto& g = m.at("gravity_error");
  EXPECT_FALSE(g.separable());
  EXPECT_GT(g.max_correlation, 0.99);
  bool scale = false;
  for (const auto& a : g.aliases) scale = scale || a == "accel_M[0][0]" || a == "accel_M[2][2]";
  EXPECT_TRUE(scale) << g.reason;
  // K2 and asymmetry: confounded with each other, each detectable far below its typical size.
  EXPECT_FALSE(m.at("accel_quadratic_k2").separable());
  ASSERT_EQ(m.at("accel_quadratic_k2").confounded_with.size(), 1u);
  EXPECT_EQ(m.at("accel_quadratic_k2").confounded_with[0], "accel_asymmetry");
  EXPECT_LT(m.at("accel_quadratic_k2").threshold, 0.2 * m.at("accel_quadratic_k2").typical);
  // Time offset: no signature at all.
  EXPECT_EQ(m.at("table_time_offset").no_signature, 1);
}

TEST(EffectDetectability, ALongerRunSeparatesWhatShortCannot) {
  const auto s = analyse("short");
  const auto f = analyse("factory-std");
  for (const char* name : {"thermal_drift", "table_nonorthogonality"}) {
    EXPECT_FALSE(s.at(name).separable()) << name << " on short";
    EXPECT_TRUE(f.at(name).separable()) << name << " on factory-std: " << f.at(name).reason;
  }
  // Longer rests lower the threshold of a static effect (σ of rest means ∝ 1/√T).
  EXPECT_LT(f.at("gyro_g_sensitivity").threshold, s.at("gyro_g_sensitivity").threshold);
}
