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

namespace {

/// One pass over a sequence, collecting every issue with its line and step (the table's limits,
/// each rest and rotation, the running duration).
class Validator {
 public:
  Validator(const Sequence& seq, const TableLimits& lim)
      : seq_(seq), lim_(lim), outer_deg_(seq.start.outer_deg), inner_deg_(seq.start.inner_deg) {}

  std::vector<ValidationIssue> run() {
    check_start();
    for (size_t i = 0; i < seq_.steps.size(); ++i) {
      const Step& st = seq_.steps[i];
      const int idx = static_cast<int>(i);
      const std::string label = step_label(i);
      if (st.kind == StepKind::kRest)
        check_rest(st, idx, label);
      else
        check_rotation(st, i, label);
      check_duration(st, idx, label);
    }
    if (!any_rotation_)
      add(0, -1, "the sequence has no rotation: a calibration needs rotations between rests");
    return std::move(issues_);
  }

 private:
  void add(int line, int step, std::string msg) { issues_.push_back({std::move(msg), line, step}); }

  void check_angle(Axis axis, double deg, int line, int step, const std::string& what) {
    const double lo = axis == Axis::kOuter ? lim_.outer_min_deg : lim_.inner_min_deg;
    const double hi = axis == Axis::kOuter ? lim_.outer_max_deg : lim_.inner_max_deg;
    if (!std::isfinite(deg)) {
      add(line, step, what + ": " + axis_name(axis) + " angle is not finite");
    } else if (deg < lo || deg > hi) {
      add(line, step,
          what + " puts the " + axis_name(axis) + " axis at " + fmt(deg) +
              " deg, outside its limits [" + fmt(lo) + ", " + fmt(hi) + "] deg");
    }
  }

  /// Start pose and initial rest: the rest before the first rotation.
  void check_start() {
    const int start_line = seq_.start.line;
    check_angle(Axis::kOuter, seq_.start.outer_deg, start_line, -1, "[start]");
    check_angle(Axis::kInner, seq_.start.inner_deg, start_line, -1, "[start]");
    const int rest0_line = seq_.start.rest_line ? seq_.start.rest_line : start_line;
    if (!(std::isfinite(seq_.start.rest_s) && seq_.start.rest_s > 0.0)) {
      add(rest0_line, -1, "initial rest_s must be finite and > 0, got " + fmt(seq_.start.rest_s));
      duration_ok_ = false;
      return;
    }
    if (seq_.start.rest_s < lim_.min_rest_s)
      add(rest0_line, -1,
          "initial rest of " + fmt(seq_.start.rest_s) + " s is shorter than the minimum rest of " +
              fmt(lim_.min_rest_s) + " s");
    total_s_ += seq_.start.rest_s;
  }

  void check_rest(const Step& st, int idx, const std::string& label) {
    const int line = st.value_line ? st.value_line : st.line;
    if (!(std::isfinite(st.duration_s) && st.duration_s > 0.0)) {
      add(line, idx, label + ": rest_s must be finite and > 0, got " + fmt(st.duration_s));
      duration_ok_ = false;
      return;
    }
    if (st.duration_s < lim_.min_rest_s)
      add(line, idx,
          label + ": rest of " + fmt(st.duration_s) + " s is shorter than the minimum rest of " +
              fmt(lim_.min_rest_s) + " s");
    total_s_ += st.duration_s;
  }

  /// Rate and acceleration within the table's limits, exactly one of by_deg / to_deg; false when
  /// the rotation's timing cannot be computed.
  bool check_kinematics(const Step& st, int idx, const std::string& label) {
    const int rate_line = st.rate_line ? st.rate_line : st.line;
    const int accel_line = st.accel_line ? st.accel_line : st.line;
    bool ok = true;
    if (!(std::isfinite(st.rate_dps) && st.rate_dps > 0.0)) {
      add(rate_line, idx, label + ": rate_dps must be finite and > 0, got " + fmt(st.rate_dps));
      ok = false;
    } else if (st.rate_dps > lim_.max_rate_dps) {
      add(rate_line, idx,
          label + ": rate of " + fmt(st.rate_dps) + " deg/s exceeds the table limit of " +
              fmt(lim_.max_rate_dps) + " deg/s");
    }
    if (!(std::isfinite(st.accel_dps2) && st.accel_dps2 > 0.0)) {
      add(accel_line, idx,
          label + ": accel_dps2 must be finite and > 0, got " + fmt(st.accel_dps2));
      ok = false;
    } else if (st.accel_dps2 > lim_.max_accel_dps2) {
      add(accel_line, idx,
          label + ": acceleration of " + fmt(st.accel_dps2) +
              " deg/s^2 exceeds the table limit of " + fmt(lim_.max_accel_dps2) + " deg/s^2");
    }
    if (st.by_deg.has_value() == st.to_deg.has_value()) {
      add(st.value_line ? st.value_line : st.line, idx,
          label + ": a rotation needs exactly one of by_deg / to_deg");
      ok = false;
    }
    return ok;
  }

  void check_rotation(const Step& st, size_t i, const std::string& label) {
    const int idx = static_cast<int>(i);
    any_rotation_ = true;
    const int value_line = st.value_line ? st.value_line : st.line;
    bool kinematics_ok = check_kinematics(st, idx, label);
    double& axis_deg = st.axis == Axis::kOuter ? outer_deg_ : inner_deg_;
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
    if (kinematics_ok && duration_ok_)
      total_s_ += rotation_timing(std::abs(delta_deg), st.rate_dps, st.accel_dps2).total_s();
    else
      duration_ok_ = false;
    // The estimators compare attitude at the rest before and the rest after each rotation.
    const bool rest_follows =
        i + 1 < seq_.steps.size() && seq_.steps[i + 1].kind == StepKind::kRest;
    if (!rest_follows)
      add(st.line, idx,
          label +
              ": rotation is not followed by a rest step (the calibration "
              "needs a rest before and after every rotation)");
  }

  /// The running duration, reported once where it first exceeds the limit.
  void check_duration(const Step& st, int idx, const std::string& label) {
    if (!duration_ok_ || duration_reported_ || total_s_ <= lim_.max_duration_s) return;
    add(st.line, idx,
        label + ": the sequence exceeds the maximum duration of " + fmt(lim_.max_duration_s) +
            " s here (" + fmt(total_s_) + " s so far)");
    duration_reported_ = true;
  }

  const Sequence& seq_;
  const TableLimits& lim_;
  std::vector<ValidationIssue> issues_;
  double outer_deg_, inner_deg_;
  double total_s_ = 0.0;
  bool duration_ok_ = true, any_rotation_ = false, duration_reported_ = false;
};

}  // namespace

std::vector<ValidationIssue> validate(const Sequence& seq, const TableLimits& lim) {
  return Validator(seq, lim).run();
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
