#pragma once
// MEMS-grade hand-placed runs for the tests of issue #21: the truth simulator's field mode turns a
// unit far from nominal (gyro offsets of 2.5–5 °/s on every axis, scales ±25 %, misalignments up to
// 50 mrad, accelerometer biases up to 200 mg, the MEMS grade's noise) by hand through 38
// positions with rests of 3–11 s after a 50 s rest, as the public recording of issue #21 was
// taken (tests/data/imu_tk_xsens).
#include <random>

#include "calib/core/conventions.hpp"
#include "calib/core/site_presets.hpp"
#include "calib/core/unit_grade.hpp"
#include "calib/sim/field_sim.hpp"
#include "sequences/profile_generator.hpp"

namespace imucal::calib::testing {

/// 38 hand rotations (60 °/s, 200 °/s²) through varied attitudes, rests drawn so that the field
/// simulator's ±20 % duration jitter leaves them within 3–11 s; `cruise_deg` > 0 adds a slow
/// constant-rate turn about the vertical (a table's cruise) after the first rest.
inline sequences::MotionProfile hand_placed_profile(uint64_t seed, double cruise_deg = 0.0) {
  sequences::Sequence seq;
  seq.name = "hand-placed-38";
  seq.start.rest_s = 50.0;
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> rest(3.0 / 0.8, 11.0 / 1.2);
  auto rotate = [&](sequences::Axis axis, double by_deg, double rate_dps, double accel_dps2) {
    sequences::Step s;
    s.kind = sequences::StepKind::kRotate;
    s.axis = axis;
    s.by_deg = by_deg;
    s.rate_dps = rate_dps;
    s.accel_dps2 = accel_dps2;
    seq.steps.push_back(s);
  };
  auto pause = [&](double duration_s) {
    sequences::Step s;
    s.kind = sequences::StepKind::kRest;
    s.duration_s = duration_s;
    seq.steps.push_back(s);
  };
  if (cruise_deg > 0.0) {
    rotate(sequences::Axis::kInner, cruise_deg, 10.0, 10.0);
    pause(rest(rng));
  }
  const double angles[] = {90.0, 45.0, -135.0, 180.0, 60.0, -90.0};
  for (int i = 0; i < 38; ++i) {
    rotate(i % 2 ? sequences::Axis::kInner : sequences::Axis::kOuter, angles[i % 6], 60.0, 200.0);
    pause(rest(rng));
  }
  return sequences::generate_profile(seq);
}

inline UnitModel mems_unit(uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  auto pick = [&](double envelope) { return envelope * u(rng); };
  UnitModel unit;
  // Offsets of 2.5–5 °/s on every axis, signs at random: the magnitude detector's 1 °/s is far.
  for (int i = 0; i < 3; ++i)
    unit.params.gyro_bias_radps(i) = (u(rng) > 0 ? 5.0 : -5.0) * (0.75 + 0.25 * u(rng)) * kDegToRad;
  unit.params.accel_bias_mps2 = Eigen::Vector3d(pick(0.2), pick(0.2), 0.19) * kStandardGravity_mps2;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      unit.params.gyro_M(i, j) = i == j ? pick(0.25) : pick(0.05);
      unit.params.accel_M(i, j) = i == j ? pick(0.10) : pick(0.05);
    }
  const GradePrior mems = grade_prior(Grade::kMems);
  unit.noise.arw_rad_per_sqrt_s = mems.arw_rad_per_sqrt_s;
  unit.noise.vrw_mps_per_sqrt_s = mems.vrw_mps_per_sqrt_s;
  return unit;
}

inline FieldSimResult simulate_mems(uint64_t seed, double cruise_deg = 0.0) {
  FieldSimOptions o;
  o.setting = Setting::kLand;
  o.seed = seed;
  o.rate_hz = 100.0;
  return simulate_field(hand_placed_profile(seed, cruise_deg), demo_factory_site(), mems_unit(seed),
                        o);
}

}  // namespace imucal::calib::testing
