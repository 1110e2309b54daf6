#include "calib/sim/hand_placement.hpp"

#include <random>
#include <stdexcept>

#include "sequences/profile_generator.hpp"

namespace imucal::calib::sim {

sequences::MotionProfile hand_placed_profile(uint64_t seed, const HandPlacementOptions& o) {
  if (o.positions < 1) throw std::invalid_argument("hand placement: positions must be >= 1");
  if (!(o.min_rest_s > 0.0 && o.min_rest_s <= o.max_rest_s && o.first_rest_s > 0.0))
    throw std::invalid_argument("hand placement: rests must satisfy 0 < min_rest_s <= max_rest_s");
  sequences::Sequence seq;
  seq.name = "hand-placed-" + std::to_string(o.positions);
  seq.start.rest_s = o.first_rest_s;
  std::mt19937_64 rng(seed);
  // Drawn inside [min/0.8, max/1.2] so that ±20 % jitter keeps them in [min, max] (when the range
  // allows; a narrow one is centred instead).
  const double lo = o.min_rest_s / 0.8, hi = o.max_rest_s / 1.2;
  std::uniform_real_distribution<double> rest(std::min(lo, 0.5 * (lo + hi)),
                                              std::max(hi, 0.5 * (lo + hi)));
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
  if (o.cruise_deg > 0.0) {
    rotate(sequences::Axis::kInner, o.cruise_deg, 10.0, 10.0);
    pause(rest(rng));
  }
  const double angles_deg[] = {90.0, 45.0, -135.0, 180.0, 60.0, -90.0};
  for (int i = 0; i < o.positions; ++i) {
    rotate(i % 2 ? sequences::Axis::kInner : sequences::Axis::kOuter, angles_deg[i % 6],
           o.move_rate_dps, o.move_accel_dps2);
    pause(rest(rng));
  }
  return sequences::generate_profile(seq);
}

}  // namespace imucal::calib::sim
