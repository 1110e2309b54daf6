#include "calib/calibration_pipeline.hpp"

#include <stdexcept>
#include <string>

#include "calib/data_check.hpp"

namespace imucal::calib {

namespace {

using Method = CalibrationResult (*)(const CalibrationInput&, const PipelineOptions&);

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
                         Method method) {
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

}  // namespace

PipelineResult run_calibration(const CalibrationInput& in, const PipelineOptions& opt) {
  const bool field = in.setting != Setting::kFactory;
  const MethodSelection sel = opt.methods;
  if (field && sel == MethodSelection::kNlsq)
    throw std::invalid_argument(
        std::string(
            "NLSQ needs the table's attitude reference (paper §V) and cannot calibrate a ") +
        setting_name(in.setting) + " run; use --method ains or legacy (or all: AINS + legacy)");
  // A broken stream or a wrong set-up is refused with its symptom before any method runs.
  if (opt.check_data) {
    if (opt.on_phase) opt.on_phase("checking the data");
    std::vector<DataProblem> problems = check_data(in);
    if (!problems.empty()) throw DataCheckError(std::move(problems));
  }
  const bool all = sel == MethodSelection::kAll;
  PipelineResult out;
  if (all || sel == MethodSelection::kAins) out.ains = run_method(in, opt, "AINS", run_ains);
  if ((all && !field) || sel == MethodSelection::kNlsq)
    out.nlsq = run_method(in, opt, "NLSQ", run_nlsq);
  // The legacy method needs a still platform: on land it is AINS's independent check; at sea
  // (a rocking, drifting deck) there is none, and AINS stands alone.
  if ((all && in.setting == Setting::kLand) || sel == MethodSelection::kLegacy)
    out.legacy = run_method(in, opt, "legacy", run_legacy);
  const std::optional<MethodOutcome>& second = out.nlsq ? out.nlsq : out.legacy;
  if (out.ains && second) {
    if (opt.on_phase) opt.on_phase("cross-check");
    out.crosscheck = cross_check(out.ains->result, out.ains->metrics, second->result,
                                 second->metrics, opt.crosscheck);
  }
  // The cross-check already holds both methods' metrics to their limits; a method on its own
  // gets that check here.
  LimitCheckOptions limits = opt.limits;
  limits.max_orientation_rmse_mdeg = opt.crosscheck.max_orientation_rmse_mdeg;
  limits.max_accel_rmse_ug = opt.crosscheck.max_accel_rmse_ug;
  for (const auto* m : {&out.ains, &out.nlsq, &out.legacy})
    if (*m) check_limits((*m)->result, (*m)->metrics, !out.crosscheck, limits, out.limits);
  return out;
}

}  // namespace imucal::calib
