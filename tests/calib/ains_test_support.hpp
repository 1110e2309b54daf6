#pragma once
// Shared set-up of the AINS / CRLB tests: station site, table geometries, motion profiles, and
// the comparison of estimates with the simulator's truth. Truth always comes from the simulator.
#include <cmath>
#include <string>
#include <vector>

#include "calib/ains/ains.hpp"
#include "calib/core/calibration_input.hpp"
#include "calib/core/conventions.hpp"
#include "calib/core/rotation.hpp"
#include "calib/core/site_presets.hpp"
#include "calib/core/table_model.hpp"
#include "calib/sim/truth_sim.hpp"
#include "sequences/library.hpp"
#include "sequences/motion_profile.hpp"

namespace imucal::calib::testing {
using namespace imucal::calib::core;
using namespace imucal::calib::effects;
using namespace imucal::calib::sim;

inline Site factory_site() { return demo_factory_site(); }

/// One constant-acceleration move of one axis by `by_deg` at 10 deg/s (10 deg/s² ramps), then a
/// rest.
inline void append_move(sequences::MotionProfile& p, bool outer, double by_deg, double rest_s) {
  const double rate = 10.0 * kDegToRad, acc = 10.0 * kDegToRad;
  const double dir = by_deg >= 0 ? 1.0 : -1.0;
  const double t_ramp = rate / acc;
  const double t_cruise = (std::abs(by_deg) * kDegToRad - acc * t_ramp * t_ramp) / rate;
  double angle = outer ? p.segments.back().outer.angle0_rad : p.segments.back().inner.angle0_rad;
  const double fixed =
      outer ? p.segments.back().inner.angle0_rad : p.segments.back().outer.angle0_rad;
  double rate0 = 0.0;
  auto push = [&](double dur, double a, sequences::SegmentKind kind) {
    sequences::ProfileSegment s;
    s.t0_s = p.segments.back().t1_s;
    s.t1_s = s.t0_s + dur;
    s.kind = kind;
    const sequences::AxisMotion moving{angle, rate0, a}, still{fixed, 0.0, 0.0};
    s.outer = outer ? moving : still;
    s.inner = outer ? still : moving;
    p.segments.push_back(s);
    angle += rate0 * dur + 0.5 * a * dur * dur;
    rate0 += a * dur;
  };
  push(t_ramp, dir * acc, sequences::SegmentKind::kMove);
  push(t_cruise, 0.0, sequences::SegmentKind::kMove);
  push(t_ramp, -dir * acc, sequences::SegmentKind::kMove);
  rate0 = 0.0;
  push(rest_s, 0.0, sequences::SegmentKind::kRest);
}

inline sequences::MotionProfile start_profile(const std::string& name, double rest_s) {
  sequences::MotionProfile p;
  p.name = name;
  sequences::ProfileSegment s;
  s.t0_s = 0.0;
  s.t1_s = rest_s;
  s.kind = sequences::SegmentKind::kRest;
  p.segments.push_back(s);
  return p;
}

/// Rank-deficient on purpose: inner-axis rotations only at outer = 0. With the default geometry
/// (calib/core/table_model.hpp: outer axis horizontal, inner axis = platform normal = body z,
/// vertical at outer = 0) the body turns about z only and body z always points down.
inline sequences::MotionProfile inner_only_profile() {
  sequences::MotionProfile p = start_profile("inner-only", 30.0);
  for (double d : {90.0, 90.0, -270.0, 90.0, 180.0, -90.0, -90.0, 180.0})
    append_move(p, false, d, 25.0);
  return p;
}

/// The library's short check sequence (sequences/short.toml).
inline sequences::MotionProfile short_profile() { return sequences::load_profile("short"); }

inline SimResult simulate_run(const sequences::MotionProfile& profile, const TableGeometry& geom,
                              const UnitModel& unit, uint64_t seed, bool noise) {
  SimOptions so;
  so.seed = seed;
  so.noise = noise;
  return simulate(profile, geom, factory_site(), unit, so);
}

}  // namespace imucal::calib::testing
