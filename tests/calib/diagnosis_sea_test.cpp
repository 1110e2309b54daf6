// The gap diagnosis at sea (issue #21 item 4): a sea run has no still rest, so its residuals are
// the AINS filter's GNSS innovations with the sensor parameters held at the hypothesis
// (calib/ains/ains_innovations.hpp, calib/diagnosis/gap_model.hpp "Sea runs"). Expectations come
// from the field simulator's truth: the injected effects, the white noise of its GNSS fixes.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>

#include "calib/ains/ains.hpp"
#include "calib/ains/ains_innovations.hpp"
#include "calib/core/calibration_input.hpp"
#include "calib/core/site_presets.hpp"
#include "calib/diagnosis/diagnosis.hpp"
#include "calib/diagnosis/diagnosis_validation.hpp"
#include "calib/diagnosis/gap_model.hpp"
#include "calib/sim/field_sim.hpp"
#include "sequences/library.hpp"
#include "tests/support/diagnosis_finding.hpp"
#include "tests/support/field_unit.hpp"

using namespace imucal;
using namespace imucal::calib;
using namespace imucal::calib::ains;
using namespace imucal::calib::core;
using namespace imucal::calib::diagnosis;
using namespace imucal::calib::effects;
using namespace imucal::calib::sim;

namespace {

DiagnosisInput simulate_sea(const UnitModel& unit, const char* sequence, uint64_t seed) {
  FieldSimOptions o;
  o.setting = Setting::kSea;
  o.seed = seed;
  const FieldSimResult sim =
      simulate_field(sequences::load_profile(sequence), demo_factory_site(), unit, o);
  DiagnosisInput in;
  in.cal = input_from_field_data(Setting::kSea, sim.imu, sim.gnss, demo_factory_site(), unit.noise);
  return in;
}

}  // namespace

// Under the model the filter's innovations are white: at the true parameters every horizontal
// fix's whitened innovation is N(0, 1) (mean and mean square over ~1000 of them), and an effect
// the calibration does not model raises them.
TEST(AinsInnovations, AtTheTruthTheGnssInnovationsAreStandardNormal) {
  const UnitModel unit = test_support::field_unit();
  const DiagnosisInput run = simulate_sea(unit, "short", 3);
  const AinsInnovations a = ains_innovations(run.cal, unit.params);
  double sum = 0.0, sum2 = 0.0;
  int n = 0;
  for (const AinsInnovation& r : a.rows) {
    if (r.kind != AinsInnovation::kGnssNorth && r.kind != AinsInnovation::kGnssEast) continue;
    const double w = r.nu / std::sqrt(r.s);
    sum += w;
    sum2 += w * w;
    ++n;
  }
  ASSERT_GT(n, 800);
  std::printf("%d GNSS innovations: mean %.3f, mean square %.3f\n", n, sum / n, sum2 / n);
  EXPECT_LT(std::abs(sum / n), 4.0 / std::sqrt(n));
  EXPECT_NEAR(sum2 / n, 1.0, 4.0 * std::sqrt(2.0 / n));
}

// A null sea run is consistent with the model, and the candidates a sea run cannot judge are
// marked so, saying why (no table; the latitude from the fixes; no still rest for the noise).
TEST(SeaDiagnosis, NullSeaRunIsConsistentAndSaysWhatItCannotJudge) {
  const UnitModel unit = test_support::field_unit();
  const DiagnosisInput run = simulate_sea(unit, "factory-std", 5);
  const CalibrationResult cal = calibrate_ains(run.cal);
  const DiagnosisResult d = diagnose(run, cal.params);
  std::printf("%s\n", d.summary.c_str());
  EXPECT_EQ(d.verdict, "consistent") << d.summary;
  EXPECT_TRUE(d.innovation_residuals);
  ASSERT_EQ(d.components.size(), 2u);
  EXPECT_EQ(d.components[0], "gnss north");
  EXPECT_GT(d.held_out.gap_before, 0.8);
  EXPECT_LT(d.held_out.gap_before, 1.2);
  EXPECT_TRUE(std::isnan(d.twin_gap));
  for (const auto& c : d.candidates) {
    const EffectKind k = effect_info(c.id).kind;
    if (k == EffectKind::kTable) {
      EXPECT_NE(c.note.find("no table (sea)"), std::string::npos) << c.name;
    }
    if (k == EffectKind::kStochastic) {
      EXPECT_NE(c.note.find("not assessed at sea"), std::string::npos) << c.name;
    }
    if (c.id == EffectId::kLatitudeError) {
      EXPECT_NE(c.note.find("GNSS fixes"), std::string::npos);
    }
    if (c.id == EffectId::kGravityError) {
      EXPECT_NE(c.note.find("not separable"), std::string::npos) << c.note;  // a common scale
    }
  }
}

// A withheld effect of the unit on a sea run is named with its size: every fitted parameter within
// 4σ of the injected value, the held-out gap shrunk.
TEST(SeaDiagnosis, WithheldEffectsOfASeaRunAreNamedWithTheirSize) {
  struct Case {
    EffectId id;
    Effects fx;
  };
  // Each at about 3-4x its detection threshold on factory-std at sea (`imucal validate-diagnosis
  // --setting sea`), in the catalogue's typical pattern.
  auto typical_at = [](EffectId id, double magnitude) {
    Effects fx;
    set_effect_vector(fx, id, scaled_typical(effect_info(id), magnitude, 1.0));
    return fx;
  };
  const Effects gs = typical_at(EffectId::kGyroGSensitivity, 0.3);  // °/h/g (threshold 0.09)
  const Effects size = typical_at(EffectId::kSizeEffect, 130.0);    // mm (threshold 32)
  const Effects skew = typical_at(EffectId::kGyroAccelSkew, 0.6);   // ms (threshold 0.17)
  const Effects warm = typical_at(EffectId::kThermalDrift, 8.0);    // x typical (threshold 2)
  for (const Case& c :
       {Case{EffectId::kGyroGSensitivity, gs}, Case{EffectId::kSizeEffect, size},
        Case{EffectId::kGyroAccelSkew, skew}, Case{EffectId::kThermalDrift, warm}}) {
    UnitModel unit = test_support::field_unit();
    unit.effects = c.fx;
    const DiagnosisInput run = simulate_sea(unit, "factory-std", 11);
    const CalibrationResult cal = calibrate_ains(run.cal);
    const DiagnosisResult d = diagnose(run, cal.params);
    test_support::expect_finding(d, c.id, c.fx);
    EXPECT_GT(d.held_out.shrinkage, 0.7);
  }
}

// The model's own refusals: a sea run needs its GNSS fixes (the residuals are their innovations).
TEST(SeaDiagnosis, ASeaRunWithoutFixesIsRefusedNamingWhy) {
  const UnitModel unit = test_support::field_unit();
  DiagnosisInput run = simulate_sea(unit, "short", 5);
  run.cal.gnss.clear();
  try {
    diagnose(run, unit.params);
    FAIL() << "a sea run without fixes was diagnosed";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("without GNSS fixes"), std::string::npos) << e.what();
  }
}
