// The gap diagnosis without a table (issue #21 item 4): a land run taken by hand has no attitude
// reference, so the residual model carries each rest's attitude as an unknown
// (calib/diagnosis/gap_model.hpp). Expectations come from the field simulator's truth: its true
// attitude at every sample, the injected effects.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>

#include "calib/core/calibration_input.hpp"
#include "calib/core/rotation.hpp"
#include "calib/core/site_presets.hpp"
#include "calib/diagnosis/diagnosis.hpp"
#include "calib/diagnosis/gap_model.hpp"
#include "calib/effects/effect_compensation.hpp"
#include "calib/sim/field_sim.hpp"
#include "sequences/library.hpp"
#include "tests/support/diagnosis_finding.hpp"
#include "tests/support/field_unit.hpp"

using namespace imucal;
using namespace imucal::calib;
using namespace imucal::calib::core;
using namespace imucal::calib::diagnosis;
using namespace imucal::calib::effects;
using namespace imucal::calib::sim;

namespace {

struct LandRun {
  FieldSimResult sim;
  DiagnosisInput in;
};

LandRun simulate_land(const UnitModel& unit, bool noise, uint64_t seed) {
  const Setting setting = Setting::kLand;
  FieldSimOptions o;
  o.setting = setting;
  o.noise = noise;
  o.seed = seed;
  LandRun r;
  r.sim = simulate_field(sequences::load_profile("short"), demo_factory_site(), unit, o);
  r.in.cal = input_from_field_data(setting, r.sim.imu, r.sim.gnss, demo_factory_site(), unit.noise);
  return r;
}

}  // namespace

// Noise-free data at the true parameters: the estimated rest attitudes are the true ones (levelled
// on each rest, carried across the moves, the common heading from the Earth rate the rests see),
// and every residual vanishes against its own noise σ.
TEST(TableFreeGapModel, NoiseFreeLandRunFindsTheRestAttitudesAndLeavesNoResidual) {
  const UnitModel unit = test_support::field_unit();
  const LandRun run = simulate_land(unit, false, 3);
  const GapModel model(run.in, 100, &unit.params);
  ASSERT_TRUE(model.table_free());
  ASSERT_GE(model.rests().size(), 10u);
  EXPECT_EQ(model.attitude_unknowns(), 3 * static_cast<int>(model.rests().size()));
  double worst_rad = 0.0;
  for (size_t r = 0; r < model.rests().size(); ++r) {
    const RestPeriod& p = model.rests()[r];
    const Eigen::Matrix3d& truth = run.sim.C_bn[p.begin + p.size() / 2];
    worst_rad = std::max(
        worst_rad, matrix_to_rotvec(model.rest_attitude_estimate(r) * truth.transpose()).norm());
  }
  std::printf("worst rest attitude error %.3g rad\n", worst_rad);
  // Heading included: navigation-grade gyros resolve the Earth rate at every rest.
  EXPECT_LT(worst_rad, 1e-6);
  const Eigen::VectorXd w = model.whiten(model.residuals(unit.params, Effects{}));
  EXPECT_LT(w.cwiseAbs().maxCoeff(), 0.05) << "max |whitened residual|";
}

// A withheld effect on a land run is named with its size: the field simulator's g-sensitivity and
// size effect (the accelerometers' lever arms turned by the hand) are the ones the model subtracts.
TEST(TableFreeDiagnosis, WithheldEffectsOfALandRunAreNamedWithTheirSize) {
  struct Case {
    EffectId id;
    Effects fx;
  };
  Effects gs, size;
  gs.gyro_g_sens = Eigen::Matrix3d::Identity() * 1e-7;  // 0.2 °/h/g per axis
  size.accel_lever_arm_m[0] = Eigen::Vector3d(0.0, 0.04, 0.0);
  size.accel_lever_arm_m[1] = Eigen::Vector3d(0.0, 0.0, 0.04);
  size.accel_lever_arm_m[2] = Eigen::Vector3d(0.04, 0.0, 0.0);
  for (const Case& c : {Case{EffectId::kGyroGSensitivity, gs}, Case{EffectId::kSizeEffect, size}}) {
    UnitModel unit = test_support::field_unit();
    unit.effects = c.fx;
    const LandRun run = simulate_land(unit, true, 11);
    const DiagnosisResult d = diagnose(run.in, test_support::field_unit().params);
    const CandidateResult* best = test_support::expect_finding(d, c.id, c.fx);
    ASSERT_NE(best, nullptr);
    // The g-sensitivity's injected terms are resolved too; the lever arms on this short sequence
    // only as a set (their directions correlate up to 0.95 with the calibration's: σ of a
    // component ~0.5 m, yet together they remove the whole gap).
    const Eigen::VectorXd truth = effect_vector(c.fx, c.id);
    for (size_t j = 0; j < best->params.size() && c.id == EffectId::kGyroGSensitivity; ++j) {
      const double t = truth(static_cast<int>(j)) * effect_info(c.id).params[j].si_to_human;
      if (t == 0.0) continue;
      EXPECT_LT(best->params[j].sigma, 0.25 * std::abs(t))
          << best->params[j].name << " not resolved";
    }
    EXPECT_GT(d.held_out.shrinkage, 0.7);
    // No table: its effects are not candidates, and there is no simulated twin.
    for (const auto& k : d.candidates) {
      if (effect_info(k.id).kind == EffectKind::kTable) {
        EXPECT_FALSE(k.separable) << k.name;
      }
    }
    EXPECT_TRUE(std::isnan(d.twin_gap));
  }
}

// A null land run is consistent, and its held-out gap is near 1: a move's relative heading, which
// nothing else sees, is not asked of the held-out segments (it would be noise of any size).
TEST(TableFreeDiagnosis, NullLandRunIsConsistentAndItsHeldOutGapNearOne) {
  const UnitModel unit = test_support::field_unit();
  for (uint64_t seed : {21u, 22u}) {
    const LandRun run = simulate_land(unit, true, seed);
    const DiagnosisResult d = diagnose(run.in, unit.params);
    EXPECT_EQ(d.verdict, "consistent") << d.summary;
    EXPECT_GT(d.held_out.gap_before, 0.6) << seed;
    EXPECT_LT(d.held_out.gap_before, 1.6) << seed;
    // The base refit moves the sensor parameters only; ς has no meaning without a table.
    EXPECT_TRUE(d.base.table_misalignment_rad.isZero());
  }
}

// What `calibrate --compensate` does with a diagnosis' finding: the effect taken out of the data
// leaves the run the unit would have recorded without it (to the second order the effect is
// evaluated at measured rather than true kinematics), and only the unit's own effects come out.
TEST(EffectCompensation, RemovingAnEffectLeavesTheRunWithoutIt) {
  Effects fx;
  fx.gyro_g_sens = Eigen::Matrix3d::Identity() * 1e-7;
  fx.gyro_accel_skew_s = 2e-3;
  UnitModel with = test_support::field_unit(), without = test_support::field_unit();
  with.effects = fx;
  ImuSeries imu = simulate_land(with, false, 4).sim.imu;
  const ImuSeries clean = simulate_land(without, false, 4).sim.imu;
  double effect = 0.0, left = 0.0;
  for (size_t k = 0; k < imu.size(); ++k)
    effect = std::max(effect, (imu[k].dtheta_rad - clean[k].dtheta_rad).norm() +
                                  (imu[k].dv_mps - clean[k].dv_mps).norm());
  remove_sensor_effects(imu, fx, with.params);
  for (size_t k = 0; k < imu.size(); ++k)
    left = std::max(left, (imu[k].dtheta_rad - clean[k].dtheta_rad).norm() +
                              (imu[k].dv_mps - clean[k].dv_mps).norm());
  std::printf("the effects per sample up to %.3g (rad + m/s); left after removal %.3g\n", effect,
              left);
  EXPECT_GT(effect, 1e-5);
  EXPECT_LT(left, 1e-3 * effect);
  Effects table;
  table.table_nonorthogonality_rad = 1e-5;
  EXPECT_THROW(remove_sensor_effects(imu, table, with.params), std::invalid_argument);
}

// The table-free fit's σ are honest: over land runs with a withheld g-sensitivity, the fitted
// terms' error over their σ is N(0, 1) (RMS within [0.7, 1.4]).
TEST(TableFreeDiagnosis, TheFittedEffectsSigmaIsHonestMonteCarlo) {
  Effects fx;
  fx.gyro_g_sens << 1e-7, 2e-8, 0.0, -3e-8, 8e-8, 1e-8, 0.0, 4e-8, 1.2e-7;
  UnitModel unit = test_support::field_unit();
  unit.effects = fx;
  const Eigen::VectorXd truth = effect_vector(fx, EffectId::kGyroGSensitivity);
  double sum2 = 0.0;
  int n = 0;
  for (uint64_t seed = 40; seed < 48; ++seed) {
    const LandRun run = simulate_land(unit, true, seed);
    DiagnosisOptions opt;
    opt.candidates = {EffectId::kGyroGSensitivity};
    const DiagnosisResult d = diagnose(run.in, test_support::field_unit().params, opt);
    ASSERT_TRUE(d.best) << d.summary;
    const CandidateResult& c = d.candidates[*d.best];
    const EffectInfo& e = effect_info(c.id);
    for (size_t j = 0; j < c.params.size(); ++j) {
      const double t = truth(static_cast<int>(j)) * e.params[j].si_to_human;
      const double z = (c.params[j].value - t) / c.params[j].sigma;
      sum2 += z * z;
      ++n;
    }
  }
  const double rms = std::sqrt(sum2 / n);
  std::printf("g-sensitivity on land, RMS(error/sigma) %.3f over %d terms\n", rms, n);
  EXPECT_GE(rms, 0.7);
  EXPECT_LE(rms, 1.4);
}
