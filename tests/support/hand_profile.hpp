#pragma once
// A motion profile built by hand for tests that must not depend on the sequence parser:
// rests and single-axis trapezoidal moves (accelerate, cruise, decelerate).
#include <cmath>

#include "calib/core/conventions.hpp"
#include "sequences/motion_profile.hpp"

namespace imucal::test_support {

class HandProfile {
 public:
  explicit HandProfile(double outer0_deg = 0.0, double inner0_deg = 0.0)
      : outer_(outer0_deg * kDegToRad), inner_(inner0_deg * kDegToRad) {}

  HandProfile& rest(double duration_s) {
    sequences::ProfileSegment s;
    s.t0_s = t_;
    s.t1_s = t_ + duration_s;
    s.kind = sequences::SegmentKind::kRest;
    s.outer = {outer_, 0.0, 0.0};
    s.inner = {inner_, 0.0, 0.0};
    s.step_index = step_++;
    p_.segments.push_back(s);
    t_ += duration_s;
    return *this;
  }

  /// Rotate one axis by angle at rate with the given acceleration (trapezoid; angle > 0 or < 0).
  HandProfile& rotate(bool outer_axis, double by_deg, double rate_dps = 10.0,
                      double accel_dps2 = 10.0) {
    const double sign = by_deg < 0 ? -1.0 : 1.0;
    const double angle = std::abs(by_deg) * kDegToRad, rate = rate_dps * kDegToRad,
                 acc = accel_dps2 * kDegToRad;
    double t_acc = rate / acc;
    double cruise = angle - rate * t_acc;  // angle spent outside the ramps
    double peak = rate;
    if (cruise < 0) {  // triangular
      t_acc = std::sqrt(angle / acc);
      peak = acc * t_acc;
      cruise = 0;
    }
    const double t_cruise = cruise / peak;
    const int step = step_++;
    auto seg = [&](double dur, double rate0, double a) {
      if (dur <= 0) return;
      sequences::ProfileSegment s;
      s.t0_s = t_;
      s.t1_s = t_ + dur;
      s.kind = sequences::SegmentKind::kMove;
      s.step_index = step;
      sequences::AxisMotion moving{outer_axis ? outer_ : inner_, sign * rate0, sign * a};
      sequences::AxisMotion still{outer_axis ? inner_ : outer_, 0.0, 0.0};
      s.outer = outer_axis ? moving : still;
      s.inner = outer_axis ? still : moving;
      p_.segments.push_back(s);
      const double d = sign * (rate0 * dur + 0.5 * a * dur * dur);
      (outer_axis ? outer_ : inner_) += d;
      t_ += dur;
    };
    seg(t_acc, 0.0, acc);
    seg(t_cruise, peak, 0.0);
    seg(t_acc, peak, -acc);
    return *this;
  }

  sequences::MotionProfile build(const std::string& name = "hand") const {
    sequences::MotionProfile p = p_;
    p.name = name;
    return p;
  }

  /// A compact profile for the default table geometry (outer horizontal along north, inner = body
  /// z): every body axis up and down at rest, rotations about each body axis in both directions.
  static sequences::MotionProfile full_rank(double rest_s = 30.0) {
    HandProfile h;
    h.rest(rest_s);
    for (double d : {90.0, 90.0, -180.0})
      h.rotate(true, d).rest(rest_s);  // about body x: y down/up
    for (double d : {90.0, 90.0, -180.0}) h.rotate(false, d).rest(rest_s);  // about body z
    h.rotate(false, 90.0).rest(rest_s);                                     // inner = 90
    for (double d : {90.0, -180.0, 90.0})
      h.rotate(true, d).rest(rest_s);                                 // about body -y: x down/up
    h.rotate(true, 180.0).rest(rest_s);                               // outer = 180: z up
    for (double d : {-90.0, 180.0}) h.rotate(false, d).rest(rest_s);  // about z, z up
    h.rotate(true, -180.0).rest(rest_s);                              // back to z down
    return h.build("hand-full-rank");
  }

 private:
  sequences::MotionProfile p_;
  double t_ = 0.0;
  double outer_, inner_;
  int step_ = 0;
};

}  // namespace imucal::test_support
