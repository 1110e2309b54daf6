#include "calib/pipeline/calibration_pipeline.hpp"

#include <algorithm>
#include <exception>
#include <functional>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>

#include "calib/checks/data_check.hpp"
#include "calib/core/run_concurrently.hpp"

namespace imucal::calib::pipeline {
using namespace calib::ains;
using namespace calib::checks;
using namespace calib::core;
using namespace calib::legacy;
using namespace calib::nlsq;

namespace {

using MethodFn = std::function<CalibrationResult(const CalibrationInput&, const PipelineOptions&)>;

CalibrationResult run_ains(const CalibrationInput& in, const PipelineOptions& o) {
  return calibrate_ains(in, o.ains);
}
CalibrationResult run_nlsq(const CalibrationInput& in, const PipelineOptions& o) {
  return calibrate_nlsq(in, o.nlsq);
}
CalibrationResult run_legacy(const CalibrationInput& in, const PipelineOptions& o) {
  return calibrate_legacy(in, o.legacy);
}

/// One method and its evaluation (paper §VII) — or, without an attitude reference, the statement
/// that there is none to evaluate against.
MethodOutcome run_method(const CalibrationInput& in, const PipelineOptions& opt, const char* label,
                         const MethodFn& method) {
  auto phase = [&](const std::string& p) {
    if (opt.on_phase) opt.on_phase(p);
  };
  phase(std::string(label) + " calibration");
  MethodOutcome m;
  m.result = method(in, opt);
  if (in.has_reference_attitude()) {
    phase(std::string(label) + " evaluation");
    m.metrics = evaluate(in, m.result.params, opt.evaluation);
  } else {
    m.metrics.evaluated = false;
    m.metrics.not_evaluated_reason = std::string("no attitude reference in a ") +
                                     setting_name(in.setting) +
                                     " run: the paper's metrics need the table (evaluate the "
                                     "parameters on a factory run of the unit)";
  }
  return m;
}

/// `opt` with on_phase behind a lock: the methods may report from two threads.
PipelineOptions with_serialised_phases(const PipelineOptions& opt) {
  PipelineOptions o = opt;
  if (o.on_phase) {
    auto lock = std::make_shared<std::mutex>();
    o.on_phase = [lock, report = opt.on_phase](const std::string& phase) {
      const std::lock_guard<std::mutex> guard(*lock);
      report(phase);
    };
  }
  return o;
}

/// The raw-data checks: a broken stream or a wrong set-up is refused with its symptom.
std::vector<DataProblem> check_input(const CalibrationInput& in, const PipelineOptions& opt) {
  if (!opt.check_data) return {};
  if (opt.on_phase) opt.on_phase("checking the data");
  return check_data(in, data_check_options(in.unit_prior()));
}

/// A run of a unit that may be far from nominal (every grade but navigation), on land or on the
/// table: AINS and NLSQ cannot start from zero (a MEMS gyro's offset of degrees per second defeats
/// gyrocompassing and linearisation alike), so they start from the legacy result (issue #21). At
/// sea there is no legacy method: AINS stands alone.
bool starts_from_legacy(const CalibrationInput& in) {
  return in.setting != Setting::kSea && in.grade != Grade::kNavigation;
}

/// Heading after gyrocompassing with a gyro whose bias is known to σ_b: σ_b / (Ω cos φ). A MEMS
/// gyro's residual after legacy is of the order of the Earth rate itself, so the heading comes
/// from AINS's likelihood search (calib/ains/ains.cpp) and its prior must not hold it.
constexpr double kUnknownHeadingSigma_rad = 1.0;

/// AINS linearised about `start` (the legacy result), the prior unchanged: the grade's, centred
/// on zero. The result says where it started.
CalibrationResult run_ains_from(const CalibrationInput& in, const PipelineOptions& opt,
                                const ParamSet& start) {
  AinsOptions o = opt.ains;
  o.start = start;
  o.initial_heading_sigma_rad = std::max(o.initial_heading_sigma_rad, kUnknownHeadingSigma_rad);
  CalibrationResult r = calibrate_ains(in, o);
  r.warnings.push_back(std::string("AINS linearised about the legacy result (a ") +
                       grade_name(in.grade) +
                       " unit may be far from nominal); its prior is the grade's, centred on zero");
  return r;
}

/// Below navigation grade no table run observes the fixture's heading misalignment ς_z: only
/// gyrocompassing does, and such gyros cannot resolve the Earth rate to a useful heading. The
/// result says so instead of reporting its value (or failing the limits on it).
void describe_unresolved_heading(const CalibrationInput& in, CalibrationResult& r) {
  if (in.setting != Setting::kFactory || in.grade == Grade::kNavigation) return;
  constexpr size_t kTableHeading = ParamSet::kSize - 1;  // ς_z, the last of the flat order
  if (!r.observable[kTableHeading]) return;
  r.observable[kTableHeading] = false;
  r.unobservable_notes.push_back(
      std::string("table heading misalignment: not observable with a ") + grade_name(in.grade) +
      " unit (only gyrocompassing sees it, and these gyros cannot resolve the Earth rate)");
}

/// NLSQ linearised first about `start` (the legacy result). The result says where it started.
CalibrationResult run_nlsq_from(const CalibrationInput& in, const PipelineOptions& opt,
                                const ParamSet& start) {
  NlsqOptions o = opt.nlsq;
  o.start = start;
  CalibrationResult r = calibrate_nlsq(in, o);
  r.warnings.push_back(std::string("NLSQ linearised first about the legacy result (a ") +
                       grade_name(in.grade) + " unit may be far from nominal)");
  return r;
}

/// The data checks, the legacy method, then AINS (and on the table NLSQ) started from its result:
/// one after the other. The legacy outcome is reported only when it was asked for.
void run_methods_from_legacy(const CalibrationInput& in, const PipelineOptions& opt, bool ains,
                             bool nlsq, bool legacy, PipelineResult& out) {
  std::vector<DataProblem> problems = check_input(in, opt);
  if (!problems.empty()) throw DataCheckError(std::move(problems));
  MethodOutcome start = run_method(in, opt, "legacy", run_legacy);
  const ParamSet params = start.result.params;
  if (legacy) out.legacy = std::move(start);
  auto ains_from_legacy = [&params](const CalibrationInput& i, const PipelineOptions& o) {
    return run_ains_from(i, o, params);
  };
  auto nlsq_from_legacy = [&params](const CalibrationInput& i, const PipelineOptions& o) {
    return run_nlsq_from(i, o, params);
  };
  if (ains) out.ains = run_method(in, opt, "AINS", ains_from_legacy);
  if (nlsq) out.nlsq = run_method(in, opt, "NLSQ", nlsq_from_legacy);
}

/// The data checks, then AINS, and NLSQ or legacy, each with its evaluation. With opt.concurrent
/// (and AINS selected) a second thread (calib/core/run_concurrently.hpp) runs the checks and then
/// the second method while AINS runs: AINS only reads `in`, and if the checks fail its result is
/// dropped and DataCheckError thrown as if no method had run. Otherwise an exception of either
/// method is rethrown once both have ended.
void run_methods(const CalibrationInput& in, const PipelineOptions& opt, bool ains, bool nlsq,
                 bool legacy, PipelineResult& out) {
  if ((ains || nlsq) && starts_from_legacy(in))
    return run_methods_from_legacy(in, opt, ains, nlsq, legacy, out);
  std::optional<MethodOutcome>* second = nlsq ? &out.nlsq : legacy ? &out.legacy : nullptr;
  auto run_second = [&] {
    *second =
        nlsq ? run_method(in, opt, "NLSQ", run_nlsq) : run_method(in, opt, "legacy", run_legacy);
  };
  if (!(ains && opt.concurrent)) {
    std::vector<DataProblem> problems = check_input(in, opt);
    if (!problems.empty()) throw DataCheckError(std::move(problems));
    if (ains) out.ains = run_method(in, opt, "AINS", run_ains);
    if (second) run_second();
    return;
  }
  std::vector<DataProblem> problems;
  std::exception_ptr check_error, ains_error, second_error;
  // Both tasks keep their own errors, so that they are rethrown in the order a reader expects:
  // the data checks', then AINS', then the second method's.
  auto guarded = [](std::exception_ptr& error, auto&& task) {
    try {
      task();
      return true;
    } catch (...) {
      error = std::current_exception();
      return false;
    }
  };
  run_concurrently(
      [&] { guarded(ains_error, [&] { out.ains = run_method(in, opt, "AINS", run_ains); }); },
      [&] {
        if (!guarded(check_error, [&] { problems = check_input(in, opt); })) return;
        if (problems.empty() && second) guarded(second_error, run_second);
      });
  if (check_error) std::rethrow_exception(check_error);
  if (!problems.empty()) throw DataCheckError(std::move(problems));
  if (ains_error) std::rethrow_exception(ains_error);
  if (second_error) std::rethrow_exception(second_error);
}

}  // namespace

bool PipelineResult::limits_hold_for(Method m) const {
  for (const LimitFailure& f : limits.failures)
    if (f.method == method_name(m)) return false;
  return true;
}

PipelineResult run_calibration(const CalibrationInput& in, const PipelineOptions& opt) {
  const bool field = in.setting != Setting::kFactory;
  const MethodSelection sel = opt.methods;
  if (field && sel == MethodSelection::kNlsq)
    throw std::invalid_argument(
        std::string(
            "NLSQ needs the table's attitude reference (paper §V) and cannot calibrate a ") +
        setting_name(in.setting) + " run; use --method ains or legacy (or all: AINS + legacy)");
  const bool all = sel == MethodSelection::kAll;
  PipelineResult out;
  run_methods(in, with_serialised_phases(opt), all || sel == MethodSelection::kAins,
              (all && !field) || sel == MethodSelection::kNlsq,
              // The legacy method needs a still platform: on land it is AINS's independent check;
              // at sea (a rocking, drifting deck) there is none, and AINS stands alone.
              (all && in.setting == Setting::kLand) || sel == MethodSelection::kLegacy, out);
  for (auto* m : {&out.ains, &out.nlsq})
    if (*m) describe_unresolved_heading(in, (*m)->result);
  const std::optional<MethodOutcome>& second = out.nlsq ? out.nlsq : out.legacy;
  // The metrics' limits follow the unit's grade (a MEMS unit's noise alone leaves ~200 mdeg).
  CrossCheckOptions crosscheck = opt.crosscheck;
  const MetricLimits metric = metric_limits_for_grade(
      {crosscheck.max_orientation_rmse_mdeg, crosscheck.max_accel_rmse_ug}, in.grade);
  crosscheck.max_orientation_rmse_mdeg = metric.orientation_rmse_mdeg;
  crosscheck.max_accel_rmse_ug = metric.accel_rmse_ug;
  if (out.ains && second) {
    if (opt.on_phase) opt.on_phase("cross-check");
    out.crosscheck = cross_check(out.ains->result, out.ains->metrics, second->result,
                                 second->metrics, crosscheck);
  }
  // The cross-check already holds both methods' metrics to their limits; a method on its own
  // gets that check here.
  LimitCheckOptions limits = opt.limits;
  limits.datasheet = limits_for_grade(limits.datasheet, in.unit_prior());
  limits.max_orientation_rmse_mdeg = crosscheck.max_orientation_rmse_mdeg;
  limits.max_accel_rmse_ug = crosscheck.max_accel_rmse_ug;
  for (const auto* m : {&out.ains, &out.nlsq, &out.legacy})
    if (*m) check_limits((*m)->result, (*m)->metrics, !out.crosscheck, limits, out.limits);
  if (out.ains && out.legacy)
    out.holding =
        judge_holding_method(in, out.ains->result, out.legacy->result, opt.legacy, opt.holding);
  if (in.setting == Setting::kSea)
    out.unchecked_reason =
        "sea: AINS alone, no independent method to cross-check it (the legacy method needs a "
        "still platform)";
  return out;
}

}  // namespace imucal::calib::pipeline
