#include "sequences/profile_generator.hpp"

#include <cmath>
#include <string>

#include "sequences/sequence_error.hpp"

namespace imucal::sequences {
namespace {

constexpr double kDegToRad = M_PI / 180.0;

bool positive_finite(double x) { return std::isfinite(x) && x > 0.0; }

}  // namespace

RotationTiming rotation_timing(double angle_abs, double rate, double accel) {
  RotationTiming t;
  // Angle used by accelerating 0 -> rate and braking rate -> 0: 2 * rate^2 / (2 accel).
  const double ramp_angle = rate * rate / accel;
  if (angle_abs >= ramp_angle) {
    t.peak_rate = rate;
    t.accel_time_s = rate / accel;
    t.cruise_time_s = (angle_abs - ramp_angle) / rate;
  } else {
    // Triangular: half the angle while accelerating, peak = sqrt(angle * accel).
    t.peak_rate = std::sqrt(angle_abs * accel);
    t.accel_time_s = t.peak_rate / accel;
    t.cruise_time_s = 0.0;
  }
  return t;
}

double step_angle_change_deg(const Step& step, double current_deg) {
  if (step.by_deg) return *step.by_deg;
  if (step.to_deg) return *step.to_deg - current_deg;
  return 0.0;
}

MotionProfile generate_profile(const Sequence& seq) {
  MotionProfile prof;
  prof.name = seq.name;
  const std::string& file = seq.source_path;
  if (!positive_finite(seq.start.rest_s))
    throw SequenceError(file, seq.start.rest_line ? seq.start.rest_line : seq.start.line,
                        "initial rest_s must be finite and > 0");
  if (!std::isfinite(seq.start.outer_deg) || !std::isfinite(seq.start.inner_deg))
    throw SequenceError(file, seq.start.line, "start angles must be finite");

  // Commanded angles are tracked in degrees, exactly as the file states them, and converted once
  // per step, so a long sequence does not accumulate integration round-off.
  double outer_deg = seq.start.outer_deg;
  double inner_deg = seq.start.inner_deg;
  double t_s = 0.0;

  auto hold = [&](double deg) {
    AxisMotion m;
    m.angle0_rad = deg * kDegToRad;
    return m;
  };
  auto push_rest = [&](double duration_s, int step_index) {
    ProfileSegment s;
    s.t0_s = t_s;
    s.t1_s = t_s + duration_s;
    s.kind = SegmentKind::kRest;
    s.outer = hold(outer_deg);
    s.inner = hold(inner_deg);
    s.step_index = step_index;
    prof.segments.push_back(s);
    t_s = s.t1_s;
  };

  push_rest(seq.start.rest_s, -1);

  for (size_t i = 0; i < seq.steps.size(); ++i) {
    const Step& st = seq.steps[i];
    const int idx = static_cast<int>(i);
    if (st.kind == StepKind::kRest) {
      if (!positive_finite(st.duration_s))
        throw SequenceError(file, st.line, "rest_s must be finite and > 0");
      push_rest(st.duration_s, idx);
      continue;
    }
    if (!positive_finite(st.rate_dps))
      throw SequenceError(file, st.rate_line ? st.rate_line : st.line,
                          "rate_dps must be finite and > 0");
    if (!positive_finite(st.accel_dps2))
      throw SequenceError(file, st.accel_line ? st.accel_line : st.line,
                          "accel_dps2 must be finite and > 0");
    double& axis_deg = st.axis == Axis::kOuter ? outer_deg : inner_deg;
    const double delta_deg = step_angle_change_deg(st, axis_deg);
    if (!std::isfinite(delta_deg))
      throw SequenceError(file, st.value_line ? st.value_line : st.line,
                          "rotation angle must be finite");
    if (delta_deg == 0.0) continue;
    const double end_deg = st.to_deg ? *st.to_deg : axis_deg + delta_deg;

    const double start_rad = axis_deg * kDegToRad;
    const double end_rad = end_deg * kDegToRad;
    const double sgn = delta_deg > 0.0 ? 1.0 : -1.0;
    const double v = st.rate_dps * kDegToRad;
    const double a = st.accel_dps2 * kDegToRad;
    const RotationTiming tm = rotation_timing(std::abs(end_rad - start_rad), v, a);
    // Angle covered by the ramp as the segment evaluator computes it, so that the decelerating
    // segment, evaluated at its end, lands on end_rad up to one rounding.
    const double ramp_rad =
        tm.peak_rate * tm.accel_time_s - 0.5 * a * tm.accel_time_s * tm.accel_time_s;

    auto push_move = [&](double duration_s, double angle0_rad, double rate0, double acc) {
      ProfileSegment s;
      s.t0_s = t_s;
      s.t1_s = t_s + duration_s;
      s.kind = SegmentKind::kMove;
      s.outer = hold(outer_deg);
      s.inner = hold(inner_deg);
      AxisMotion& m = st.axis == Axis::kOuter ? s.outer : s.inner;
      m.angle0_rad = angle0_rad;
      m.rate0_radps = rate0;
      m.accel_radps2 = acc;
      s.step_index = idx;
      prof.segments.push_back(s);
      t_s = s.t1_s;
    };
    // Accelerate from rest; from 0: angle = 1/2 a t^2 = ramp (since peak = a t).
    push_move(tm.accel_time_s, start_rad, 0.0, sgn * a);
    if (tm.cruise_time_s > 0.0)
      push_move(tm.cruise_time_s, start_rad + sgn * 0.5 * a * tm.accel_time_s * tm.accel_time_s,
                sgn * tm.peak_rate, 0.0);
    push_move(tm.accel_time_s, end_rad - sgn * ramp_rad, sgn * tm.peak_rate, -sgn * a);
    axis_deg = end_deg;
  }
  return prof;
}

}  // namespace imucal::sequences
