#include "calib/input/run_input.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstring>
#include <utility>

#include "calib/checks/data_check.hpp"
#include "calib/core/conventions.hpp"
#include "calib/core/readable_number.hpp"
#include "calib/core/rotation.hpp"
#include "calib/core/run_concurrently.hpp"
#include "calib/effects/effect_compensation.hpp"

namespace imucal::calib::input {
using namespace calib::checks;
using namespace calib::effects;

namespace {

/// The shortest form that reads back as the same double (what the archive writes and says).
std::string number(double v) {
  char buf[32];
  const auto res = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, res.ptr);
}

/// The sample interval against the declared rate: catches times in ms or a wrong rate.
void check_sample_interval(const ImuSeries& imu, const RunDescription& run,
                           const SeriesNames& names) {
  const size_t n = imu.size();
  const double dt_nominal = 1.0 / run.imu_rate_hz;
  if (n < 2) return;
  std::vector<double> dts(n - 1);
  for (size_t k = 1; k < n; ++k) dts[k - 1] = imu[k].dt_s;
  std::nth_element(dts.begin(), dts.begin() + static_cast<long>(dts.size() / 2), dts.end());
  const double median = dts[dts.size() / 2];
  if (std::fabs(median - dt_nominal) > 0.05 * dt_nominal)
    throw InputError(InputError::Where::kImu,
                     "median sample interval " + number(median) + " s does not match " +
                         names.rate + " = " + number(run.imu_rate_hz) +
                         " (1/rate = " + number(dt_nominal) + " s); is " + names.time +
                         " in seconds and " + names.rate_key + " right?");
}

/// Magnitude plausibility per sample, and the mean specific force at rest against gravity.
/// is_rest(k): the rest flag of sample k (the reference's, or the rest detector's).
template <typename IsRest>
void check_magnitudes(const ImuSeries& imu, IsRest is_rest, const RunDescription& run,
                      const SeriesNames& names, const std::string& rest_source) {
  const double kMaxAccel_mps2 = 20.0 * kStandardGravity_mps2;
  const double kMaxRate_radps = 1000.0 * kDegToRad;
  double rest_f_sum = 0.0;
  size_t n_rest = 0;
  for (size_t k = 0; k < imu.size(); ++k) {
    const ImuIncrement& s = imu[k];
    const double f = s.dv_mps.norm() / s.dt_s;
    const double w = s.dtheta_rad.norm() / s.dt_s;
    if (!(f < kMaxAccel_mps2))
      throw InputError(InputError::Where::kImu,
                       "|dv|/dt = " + number(f) + " m/s^2 exceeds 20 g (dt = " + number(s.dt_s) +
                           " s); " + names.dv +
                           " must be velocity increments in m/s over one sample",
                       k);
    if (!(w < kMaxRate_radps))
      throw InputError(InputError::Where::kImu,
                       "|dtheta|/dt = " + number(w * kRadToDeg) +
                           " deg/s exceeds 1000 deg/s (dt = " + number(s.dt_s) + " s); " +
                           names.dtheta + " must be angle increments in rad over one sample",
                       k);
    if (is_rest(k)) {
      rest_f_sum += f;
      ++n_rest;
    }
  }
  if (n_rest == 0) return;
  const double g = EarthModel(run.site).gravity_mps2();
  const double f_rest = rest_f_sum / static_cast<double>(n_rest);
  // A units check (m/s per sample, not m/s²): 10 %, or as wide as the grade's own envelope lets
  // gravity read (a MEMS unit 30 % off scale is that unit; the data checks then look per rest).
  const double tol = std::max(0.1, data_check_options(run.grade).gravity_magnitude_tol);
  if (std::fabs(f_rest - g) > tol * g)
    throw InputError(InputError::Where::kImu,
                     "mean |dv|/dt over the " + std::to_string(n_rest) + " rest samples is " +
                         number(f_rest) + " m/s^2 but local gravity is " + number(g) +
                         " m/s^2; check the dv units (m/s per sample) and the " + names.at_rest +
                         " flags in " + rest_source);
}

/// Land and sea: rest periods from the IMU data; the first must serve the alignment
/// (first_rest_rule).
CalibrationInput field_input(const RunDescription& run, const ImuSeries& imu,
                             const std::vector<GnssFix>& gnss) {
  CalibrationInput in = input_from_field_data(
      run.setting, imu, run.setting == Setting::kSea ? gnss : std::vector<GnssFix>{}, run.site,
      run.noise, run.grade, run.min_rest_s);
  in.prior_overrides = run.prior_overrides;
  const FirstRestRule rule = first_rest_rule(run);
  const double t0 = imu.front().t_s;
  const std::vector<RestPeriod> rests = find_rest_periods(in, 2);
  const RestPeriod* first = rests.empty() ? nullptr : &rests.front();
  const auto span_s = [&](const RestPeriod& r) { return imu[r.end - 1].t_s - imu[r.begin].t_s; };
  if (first && imu[first->begin].t_s - t0 <= rule.latest_start_s && span_s(*first) >= rule.min_s)
    return in;
  const std::string what =
      std::string("no usable first rest in this ") + setting_name(run.setting) + " run: ";
  if (!first)
    throw InputError(InputError::Where::kImu,
                     what +
                         "no rest found in the IMU data at all (the unit must stand still at "
                         "least once: the alignment and the calibration need it)");
  const bool grades_rule = run.grade == Grade::kNavigation && run.first_rest_s <= 0.0;
  const std::string need =
      (grades_rule ? "a navigation-grade unit levels and gyrocompasses on its first rest: it must "
                     "stand still for at least " +
                         seconds_text(rule.min_s)
                   : "the first rest must last at least " + seconds_text(rule.min_s) +
                         " (the run's first_rest_s)") +
      (std::isfinite(rule.latest_start_s)
           ? ", beginning within " + seconds_text(rule.latest_start_s) + " of the first sample"
           : std::string());
  throw InputError(InputError::Where::kImu,
                   what + need + " (the first rest found in the IMU data begins at " +
                       instant_text(imu[first->begin].t_s) + " and lasts " +
                       seconds_text(span_s(*first)) + ")");
}

/// The factory reference: the attitude on the IMU time axis and the rest flag, sample by sample in
/// one pass (reserve + push_back: every page is written once, where resize() would first write
/// the default samples). Throws at the first sample whose time does not match the IMU's.
std::vector<ReferenceSample> factory_reference(const RunDescription& run, const ImuSeries& imu,
                                               const ReferenceLogs& logs,
                                               const SeriesNames& names) {
  const bool table = run.reference == ReferenceKind::kTable;
  const TableModel model(run.table);
  std::vector<ReferenceSample> reference;
  reference.reserve(imu.size());
  // The table stands still most of the time (93 % of a factory-60 run): the same encoder angles
  // give the same C_bn bit for bit, so it is computed once per change (bits compared: -0 != +0).
  Eigen::Matrix3d C_bn;
  double C_outer = 0.0, C_inner = 0.0;
  bool have_C = false;
  auto same_bits = [](double x, double y) { return std::memcmp(&x, &y, sizeof x) == 0; };
  for (size_t k = 0; k < imu.size(); ++k) {
    const double t_ref = table ? (*logs.table)[k].t_s : (*logs.attitude)[k].t_s;
    if (!(std::fabs(t_ref - imu[k].t_s) <= kTimeMatchTolerance_s))
      throw InputError(InputError::Where::kReference,
                       names.time + " = " + number(t_ref) + " does not match " +
                           names.imu_sample(k) + " " + names.time + " = " + number(imu[k].t_s) +
                           " (tolerance 1 µs); the reference must be on the IMU time axis "
                           "(interpolation is not supported yet)",
                       k);
    ReferenceSample r;
    r.t_s = imu[k].t_s;
    if (table) {
      const TableSample& s = (*logs.table)[k];
      if (!have_C || !same_bits(s.outer_rad, C_outer) || !same_bits(s.inner_rad, C_inner)) {
        C_bn = model.C_bn(s.outer_rad, s.inner_rad);
        C_outer = s.outer_rad;
        C_inner = s.inner_rad;
        have_C = true;
      }
      r.C_bn_ref = C_bn;
      r.at_rest = s.at_rest;
      r.outer_rad = s.outer_rad;
      r.inner_rad = s.inner_rad;
    } else {
      const AttitudeSample& s = (*logs.attitude)[k];
      r.C_bn_ref = euler_to_C_bn(s.roll_rad, s.pitch_rad, s.yaw_rad);
      r.at_rest = s.at_rest;
    }
    reference.push_back(r);
  }
  return reference;
}

/// Factory runs: the reference on the IMU time axis, then the checks. `owned` is the caller's IMU
/// series when it gave it up: moved into the input instead of copied.
CalibrationInput factory_input(const RunDescription& run, const ImuSeries& given, ImuSeries* owned,
                               const ReferenceLogs& logs, const SeriesNames& names) {
  if (run.reference == ReferenceKind::kNone)
    throw InputError(InputError::Where::kRun,
                     "a factory run needs a reference (" + names.reference_choice + ")");
  const bool table = run.reference == ReferenceKind::kTable;
  const size_t n = given.size();
  const size_t n_ref =
      table ? (logs.table ? logs.table->size() : 0) : (logs.attitude ? logs.attitude->size() : 0);
  if (n_ref != n)
    throw InputError(InputError::Where::kReference,
                     std::to_string(n_ref) + " data rows but " + names.imu + " has " +
                         std::to_string(n) +
                         "; the reference must be logged on the IMU time axis (one row per "
                         "IMU sample; interpolation is not supported yet)");

  CalibrationInput in;
  in.site = run.site;
  in.noise = run.noise;
  in.grade = run.grade;
  in.prior_overrides = run.prior_overrides;
  if (owned) in.imu = std::move(*owned);
  const ImuSeries& imu = owned ? in.imu : given;
  auto is_rest = [&](size_t k) {
    return table ? (*logs.table)[k].at_rest : (*logs.attitude)[k].at_rest;
  };
  // Two independent jobs, each mostly first writes to fresh memory (an hour at 100 Hz: a 37 MB
  // reference; a 26 MB copy of the series): the reference and its rest check on this thread, the
  // copy and the data checks on the other. run_concurrently reports this thread's error first,
  // which is the order of the checks one after the other.
  run_concurrently(
      [&] {
        in.reference = factory_reference(run, imu, logs, names);
        if (std::none_of(in.reference.begin(), in.reference.end(),
                         [](const ReferenceSample& r) { return r.at_rest; }))
          throw InputError(InputError::Where::kReference, "no rest periods in " + names.reference +
                                                              ": " + names.at_rest + " is never 1");
      },
      [&] {
        if (!owned) in.imu = given;
        check_sample_interval(imu, run, names);
        check_magnitudes(imu, is_rest, run, names, names.reference);
      });
  return in;
}

/// A unit mounted off the table's rotation centre (a fixture slot): its accelerometers sense the
/// offset's kinematic acceleration while the table turns, which no method models. It is the size
/// effect with one lever arm for all three accelerometers, taken out with the raw rates (the
/// unit's scale and bias errors change it by ppm of µg).
void remove_slot_lever_arm(CalibrationInput& in, const RunDescription& run) {
  if (run.lever_arm_p_m.isZero()) return;
  const Eigen::Vector3d r_b = run.table.C_bp.transpose() * run.lever_arm_p_m;
  Effects fx;
  fx.accel_lever_arm_m = {r_b, r_b, r_b};
  remove_sensor_effects(in.imu, fx, ParamSet{});
}

CalibrationInput build(const RunDescription& run, const ImuSeries& imu, ImuSeries* owned,
                       const ReferenceLogs& logs, const std::vector<GnssFix>& gnss,
                       const SeriesNames& names) {
  if (imu.empty()) throw InputError(InputError::Where::kImu, "no IMU samples");
  if (!(run.imu_rate_hz > 0.0)) throw InputError(InputError::Where::kRate, "must be > 0");
  if (run.setting == Setting::kFactory) {
    CalibrationInput in = factory_input(run, imu, owned, logs, names);
    remove_slot_lever_arm(in, run);
    return in;
  }
  // Land and sea: input_from_field_data copies the series either way.
  check_sample_interval(imu, run, names);
  CalibrationInput in = field_input(run, imu, gnss);
  check_magnitudes(
      imu, [&](size_t k) { return in.reference[k].at_rest; }, run, names,
      "the rest periods detected in " + names.imu);
  return in;
}

}  // namespace

FirstRestRule first_rest_rule(const RunDescription& run) {
  const GradePrior p = grade_prior(run.grade);
  FirstRestRule rule{p.first_rest_min_s, p.first_rest_latest_start_s};
  if (run.first_rest_s > 0.0) rule.min_s = run.first_rest_s;
  return rule;
}

CalibrationInput build_calibration_input(const RunDescription& run, const ImuSeries& imu,
                                         const ReferenceLogs& reference,
                                         const std::vector<GnssFix>& gnss,
                                         const SeriesNames& names) {
  return build(run, imu, nullptr, reference, gnss, names);
}

CalibrationInput build_calibration_input(const RunDescription& run, ImuSeries&& imu,
                                         const ReferenceLogs& reference,
                                         const std::vector<GnssFix>& gnss,
                                         const SeriesNames& names) {
  return build(run, imu, &imu, reference, gnss, names);
}

}  // namespace imucal::calib::input
