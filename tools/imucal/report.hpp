#pragma once
// Presentation of calibration results: the human table (units in every label) and the JSON
// object of `imucal calibrate --json`.
#include <nlohmann/json.hpp>
#include <optional>
#include <ostream>

#include "calib/checks/crlb.hpp"
#include "calib/pipeline/calibration_pipeline.hpp"

namespace imucal::tools {

/// {"ains": {...}, "nlsq": {...}, "crosscheck": {...}} as documented in the README.
nlohmann::json pipeline_to_json(const calib::PipelineResult& r);

/// Parameter table: one row per parameter, truth (if given), each method's estimate ± 1σ and,
/// with a truth, the normalised error (est − truth)/σ.
void print_parameter_table(std::ostream& os, const calib::PipelineResult& r,
                           const calib::ParamSet* truth);
void print_metrics_and_verdict(std::ostream& os, const calib::PipelineResult& r);
void print_evaluation(std::ostream& os, const calib::EvaluationMetrics& m);
void print_crlb(std::ostream& os, const calib::CrlbResult& crlb,
                const std::vector<std::string>& unobservable);
nlohmann::json metrics_to_json(const calib::EvaluationMetrics& m);

}  // namespace imucal::tools
