#include "sequences/validator.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "sequences/profile_generator.hpp"
#include "sequences/sequence_error.hpp"

namespace imucal::sequences {
namespace {

// A rotation smaller than this is treated as zero: it moves nothing and only adds a rest.
constexpr double kZeroAngleDeg = 1e-9;

std::string fmt(double x) {
  std::ostringstream os;
  os << x;
  return os.str();
}

std::string step_label(size_t i) { return "step #" + std::to_string(i + 1); }

}  // namespace

TableLimits effective_limits(const TableLimits& station, const DeclaredLimits& d) {
  TableLimits e = station;
  if (d.max_rate_dps) e.max_rate_dps = std::min(e.max_rate_dps, *d.max_rate_dps);
  if (d.max_accel_dps2) e.max_accel_dps2 = std::min(e.max_accel_dps2, *d.max_accel_dps2);
  if (d.min_rest_s) e.min_rest_s = std::max(e.min_rest_s, *d.min_rest_s);
  if (d.max_duration_s) e.max_duration_s = std::min(e.max_duration_s, *d.max_duration_s);
  if (d.inner_min_deg) e.inner_min_deg = std::max(e.inner_min_deg, *d.inner_min_deg);
  if (d.inner_max_deg) e.inner_max_deg = std::min(e.inner_max_deg, *d.inner_max_deg);
  if (d.outer_min_deg) e.outer_min_deg = std::max(e.outer_min_deg, *d.outer_min_deg);
  if (d.outer_max_deg) e.outer_max_deg = std::min(e.outer_max_deg, *d.outer_max_deg);
  return e;
}

std::vector<ValidationIssue> validate(const Sequence& seq, const TableLimits& lim) {
  std::vector<ValidationIssue> issues;
  auto add = [&](int line, int step, std::string msg) {
    issues.push_back({std::move(msg), line, step});
  };

  auto check_angle = [&](Axis axis, double deg, int line, int step, const std::string& what) {
    const double lo = axis == Axis::kOuter ? lim.outer_min_deg : lim.inner_min_deg;
    const double hi = axis == Axis::kOuter ? lim.outer_max_deg : lim.inner_max_deg;
    if (!std::isfinite(deg)) {
      add(line, step, what + ": " + axis_name(axis) + " angle is not finite");
    } else if (deg < lo || deg > hi) {
      add(line, step,
          what + " puts the " + axis_name(axis) + " axis at " + fmt(deg) +
              " deg, outside its limits [" + fmt(lo) + ", " + fmt(hi) + "] deg");
    }
  };

  // Start pose and initial rest: the rest before the first rotation.
  const int start_line = seq.start.line;
  check_angle(Axis::kOuter, seq.start.outer_deg, start_line, -1, "[start]");
  check_angle(Axis::kInner, seq.start.inner_deg, start_line, -1, "[start]");
  const int rest0_line = seq.start.rest_line ? seq.start.rest_line : start_line;
  bool duration_ok = true;
  double total_s = 0.0;
  if (!(std::isfinite(seq.start.rest_s) && seq.start.rest_s > 0.0)) {
    add(rest0_line, -1, "initial rest_s must be finite and > 0, got " + fmt(seq.start.rest_s));
    duration_ok = false;
  } else {
    if (seq.start.rest_s < lim.min_rest_s)
      add(rest0_line, -1,
          "initial rest of " + fmt(seq.start.rest_s) + " s is shorter than the minimum rest of " +
              fmt(lim.min_rest_s) + " s");
    total_s += seq.start.rest_s;
  }

  double outer_deg = seq.start.outer_deg;
  double inner_deg = seq.start.inner_deg;
  bool any_rotation = false;
  bool duration_reported = false;

  for (size_t i = 0; i < seq.steps.size(); ++i) {
    const Step& st = seq.steps[i];
    const int idx = static_cast<int>(i);
    const std::string label = step_label(i);
    if (st.kind == StepKind::kRest) {
      if (!(std::isfinite(st.duration_s) && st.duration_s > 0.0)) {
        add(st.value_line ? st.value_line : st.line, idx,
            label + ": rest_s must be finite and > 0, got " + fmt(st.duration_s));
        duration_ok = false;
      } else {
        if (st.duration_s < lim.min_rest_s)
          add(st.value_line ? st.value_line : st.line, idx,
              label + ": rest of " + fmt(st.duration_s) +
                  " s is shorter than the minimum rest of " + fmt(lim.min_rest_s) + " s");
        total_s += st.duration_s;
      }
    } else {
      any_rotation = true;
      const int rate_line = st.rate_line ? st.rate_line : st.line;
      const int accel_line = st.accel_line ? st.accel_line : st.line;
      const int value_line = st.value_line ? st.value_line : st.line;
      bool kinematics_ok = true;
      if (!(std::isfinite(st.rate_dps) && st.rate_dps > 0.0)) {
        add(rate_line, idx, label + ": rate_dps must be finite and > 0, got " + fmt(st.rate_dps));
        kinematics_ok = false;
      } else if (st.rate_dps > lim.max_rate_dps) {
        add(rate_line, idx,
            label + ": rate of " + fmt(st.rate_dps) + " deg/s exceeds the table limit of " +
                fmt(lim.max_rate_dps) + " deg/s");
      }
      if (!(std::isfinite(st.accel_dps2) && st.accel_dps2 > 0.0)) {
        add(accel_line, idx,
            label + ": accel_dps2 must be finite and > 0, got " + fmt(st.accel_dps2));
        kinematics_ok = false;
      } else if (st.accel_dps2 > lim.max_accel_dps2) {
        add(accel_line, idx,
            label + ": acceleration of " + fmt(st.accel_dps2) +
                " deg/s^2 exceeds the table limit of " + fmt(lim.max_accel_dps2) + " deg/s^2");
      }
      if (st.by_deg.has_value() == st.to_deg.has_value()) {
        add(value_line, idx, label + ": a rotation needs exactly one of by_deg / to_deg");
        kinematics_ok = false;
      }

      double& axis_deg = st.axis == Axis::kOuter ? outer_deg : inner_deg;
      const double delta_deg = step_angle_change_deg(st, axis_deg);
      if (!std::isfinite(delta_deg)) {
        add(value_line, idx, label + ": rotation angle is not finite");
        kinematics_ok = false;
      } else if (std::abs(delta_deg) < kZeroAngleDeg &&
                 st.by_deg.has_value() != st.to_deg.has_value()) {
        add(value_line, idx,
            label + ": rotation of zero angle (the " + std::string(axis_name(st.axis)) +
                " axis is already at " + fmt(axis_deg) + " deg)");
      } else {
        // The axis sweeps monotonically from the current to the new angle, so checking the new
        // angle suffices (the current one was checked when it was reached).
        axis_deg += delta_deg;
        if (st.to_deg) axis_deg = *st.to_deg;
        check_angle(st.axis, axis_deg, value_line, idx, label);
      }
      if (kinematics_ok && duration_ok)
        total_s += rotation_timing(std::abs(delta_deg), st.rate_dps, st.accel_dps2).total_s();
      else
        duration_ok = false;

      // The estimators compare attitude at the rest before and the rest after each rotation.
      const bool rest_follows =
          i + 1 < seq.steps.size() && seq.steps[i + 1].kind == StepKind::kRest;
      if (!rest_follows)
        add(st.line, idx,
            label +
                ": rotation is not followed by a rest step (the calibration "
                "needs a rest before and after every rotation)");
    }
    if (duration_ok && !duration_reported && total_s > lim.max_duration_s) {
      add(st.line, idx,
          label + ": the sequence exceeds the maximum duration of " + fmt(lim.max_duration_s) +
              " s here (" + fmt(total_s) + " s so far)");
      duration_reported = true;
    }
  }

  if (!any_rotation)
    add(0, -1, "the sequence has no rotation: a calibration needs rotations between rests");
  return issues;
}

void throw_if_issues(const Sequence& seq, const std::vector<ValidationIssue>& issues) {
  if (issues.empty()) return;
  std::string msg = issues.front().message;
  if (issues.size() > 1)
    msg += " (and " + std::to_string(issues.size() - 1) + " more issue" +
           (issues.size() > 2 ? "s" : "") + ")";
  throw SequenceError(seq.source_path, issues.front().line, msg);
}

void validate_or_throw(const Sequence& seq, const TableLimits& limits) {
  throw_if_issues(seq, validate(seq, limits));
}

}  // namespace imucal::sequences
