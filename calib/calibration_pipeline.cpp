#include "calib/calibration_pipeline.hpp"

namespace imucal::calib {

PipelineResult run_calibration(const CalibrationInput& in, const PipelineOptions& opt) {
  auto phase = [&](const std::string& p) {
    if (opt.on_phase) opt.on_phase(p);
  };
  PipelineResult out;
  if (opt.methods != MethodSelection::kNlsq) {
    phase("AINS calibration");
    MethodOutcome m;
    m.result = calibrate_ains(in, opt.ains);
    phase("AINS evaluation");
    m.metrics = evaluate(in, m.result.params, opt.evaluation);
    out.ains = std::move(m);
  }
  if (opt.methods != MethodSelection::kAins) {
    phase("NLSQ calibration");
    MethodOutcome m;
    m.result = calibrate_nlsq(in, opt.nlsq);
    phase("NLSQ evaluation");
    m.metrics = evaluate(in, m.result.params, opt.evaluation);
    out.nlsq = std::move(m);
  }
  if (out.ains && out.nlsq) {
    phase("cross-check");
    out.crosscheck = cross_check(out.ains->result, out.ains->metrics, out.nlsq->result,
                                 out.nlsq->metrics, opt.crosscheck);
  }
  return out;
}

}  // namespace imucal::calib
