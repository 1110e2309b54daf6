#pragma once
// The sections of the run page (tools/stationweb/run_page.cpp), each an HTML fragment with the
// element id named below; the numbers also in data attributes (SI, full precision).
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "db/history/repository.hpp"

namespace imucal::tools::stationweb {

/// "AINS", "NLSQ", "legacy": a method as people read it.
std::string method_label(db::history::Method m);
/// <table id='run-facts'>: sequence, setting, origin, slot, the method that holds, promotion,
/// operator, station, software, times, reprocessing; and <p id='archive' data-path data-sha256>.
std::string facts_table(const db::history::RunRecord& run);
/// <table id='capture'> of run_json's "capture" object (nothing if the run stored none).
std::string capture_section(const nlohmann::json& run);
/// <div id='diagnosis'>: the stored gap diagnosis, headline and every field.
std::string diagnosis_section(const nlohmann::json& run);
/// <table id='calibrations'>: per parameter, each method's value ± 1σ in human units; cells
/// <td data-method data-param data-value-si data-sigma-si>, "not observable" where so.
std::string calibration_table(const std::vector<db::history::CalibrationRecord>& calibrations);
/// Each method's convergence, iterations, run time, metrics, frame, notes and warnings.
std::string method_lines(const std::vector<db::history::CalibrationRecord>& calibrations);
/// <div id='crosscheck' data-verdict data-k-sigma>: per parameter AINS − second method, combined
/// σ, bound and status (rows <tr data-param data-diff-si data-sigma-si data-status>), and the
/// stored failures (metrics included) and parameters not compared.
std::string crosscheck_section(const db::history::RunDetails& details);

}  // namespace imucal::tools::stationweb
