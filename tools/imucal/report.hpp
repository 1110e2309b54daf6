#pragma once
// Presentation of calibration results: the human table (units in every label) and the JSON
// object of `imucal calibrate --json`.
#include <nlohmann/json.hpp>
#include <optional>
#include <ostream>

#include "calib/checks/crlb.hpp"
#include "calib/pipeline/calibration_pipeline.hpp"

namespace imucal::tools::imucal {

/// {"ains": {...}, "nlsq": {...}, "crosscheck": {...}} as documented in the README.
nlohmann::json pipeline_to_json(const calib::pipeline::PipelineResult& r);

/// Parameter table: one row per parameter, truth (if given), each method's estimate ± 1σ and,
/// with a truth, the normalised error (est − truth)/σ.
void print_parameter_table(std::ostream& os, const calib::pipeline::PipelineResult& r,
                           const calib::core::ParamSet* truth);
void print_metrics_and_verdict(std::ostream& os, const calib::pipeline::PipelineResult& r);
void print_evaluation(std::ostream& os, const calib::checks::EvaluationMetrics& m);
void print_crlb(std::ostream& os, const calib::checks::CrlbResult& crlb,
                const std::vector<std::string>& unobservable);
nlohmann::json metrics_to_json(const calib::checks::EvaluationMetrics& m);

}  // namespace imucal::tools::imucal
