#pragma once
// MEMS-grade hand-placed runs for the tests of issue #21: the truth simulator's field mode turns a
// unit drawn from the MEMS envelope (calib/sim/unit_draw.hpp: gyro offsets of 2.5–5 °/s on every
// axis, gyro scales within ±24 %, misalignments within 50 mrad, accelerometer biases within
// 200 mg, the grade's noise) by hand through 38 positions with rests of 3–11 s after a 50 s rest
// (calib/sim/hand_placement.hpp), as the public recording of issue #21 was taken
// (tests/data/imu_tk_xsens); and the factory's standard sequence turned by hand.
#include <utility>
#include <vector>

#include "calib/core/calibration_input.hpp"
#include "calib/core/conventions.hpp"
#include "calib/core/site_presets.hpp"
#include "calib/core/unit_grade.hpp"
#include "calib/sim/field_sim.hpp"
#include "calib/sim/hand_placement.hpp"
#include "calib/sim/unit_draw.hpp"
#include "sequences/library.hpp"

namespace imucal::calib::testing {
using namespace imucal::calib::core;
using namespace imucal::calib::sim;

/// The run as a MEMS unit's land calibration reads it: the grade's noise, rests by variation.
inline CalibrationInput mems_input(const FieldSimResult& sim) {
  NoiseModel noise;
  const GradePrior mems = grade_prior(Grade::kMems);
  noise.arw_rad_per_sqrt_s = mems.arw_rad_per_sqrt_s;
  noise.vrw_mps_per_sqrt_s = mems.vrw_mps_per_sqrt_s;
  return input_from_field_data(Setting::kLand, sim.imu, {}, demo_factory_site(), noise,
                               Grade::kMems);
}

/// The true rest spans [begin, end) of a simulated run (FieldSimResult::true_rest), in samples.
inline std::vector<std::pair<size_t, size_t>> true_rest_spans(const std::vector<bool>& rest) {
  std::vector<std::pair<size_t, size_t>> spans;
  for (size_t k = 0; k < rest.size();) {
    if (!rest[k]) {
      ++k;
      continue;
    }
    size_t e = k;
    while (e < rest.size() && rest[e]) ++e;
    spans.emplace_back(k, e);
    k = e;
  }
  return spans;
}

/// A MEMS unit drawn with `seed` turned by hand through `hand`'s positions, on land at 100 Hz.
inline FieldSimResult simulate_mems(uint64_t seed, const HandPlacementOptions& hand) {
  FieldSimOptions o;
  o.setting = Setting::kLand;
  o.seed = seed;
  o.rate_hz = 100.0;
  return simulate_field(hand_placed_profile(seed, hand), demo_factory_site(),
                        draw_unit(Grade::kMems, seed), o);
}

inline FieldSimResult simulate_mems(uint64_t seed, double cruise_deg = 0.0) {
  HandPlacementOptions hand;
  hand.cruise_deg = cruise_deg;
  return simulate_mems(seed, hand);
}

/// `imucal simulate --setting land --grade mems --sequence factory-std --seed SEED`: the factory's
/// standard sequence turned by hand (90-120 s rests, 38 minutes), no table.
inline FieldSimResult factory_std_by_hand(uint64_t seed) {
  FieldSimOptions o;
  o.setting = Setting::kLand;
  o.seed = seed;
  o.rate_hz = 100.0;
  UnitModel unit = draw_unit(Grade::kMems, seed);
  unit.params.table_misalignment_rad.setZero();  // no table
  return simulate_field(sequences::load_profile("factory-std"), demo_factory_site(), unit, o);
}

}  // namespace imucal::calib::testing
