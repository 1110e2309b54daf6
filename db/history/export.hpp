#pragma once
// Export of the calibration history for QA (`stationctl export [--serial SN] [--since DATE]
// --format csv|json`) and the JSON forms of the repository records (`--json` on read commands).
// Rows stream from Repository::export_rows straight to the ostream, so memory does not grow with
// the database.
//
// CSV (RFC 4180): a header row, then one row per run and method (a run without calibrations —
// failed, aborted — has one row with an empty method). Records end in CRLF; a field containing a
// comma, a double quote, CR or LF is enclosed in double quotes with inner quotes doubled. Columns,
// in order: kCsvRunColumns, then kCsvCalibrationColumns, then the 27 parameters named as in the
// parameter-set JSON (calib::core::param_info(i).name, e.g. "accel_M[0][1]") in SI units, then
// their 1-σ as "sigma.<name>", then the run's cross-check (kCsvCrosscheckColumns: k_sigma and the
// failing terms as "term: detail" joined by "; ") and its capture counters as "capture.<counter>"
// (db::archive::CaptureInfo::counters(), the names of db/archive/FORMAT.md), then its gap diagnosis
// (kCsvDiagnosisColumns). "verdict" is the run's (PASS/REVIEW/FAILED/STATION-FAULT/ABORTED/
// INTERRUPTED), "outcome_of" whose it was (unit, station, operator, daemon; empty while live, issue
// #50), "crosscheck_verdict" the cross-check's own (PASS/REVIEW), "failure_reason"
// every reason joined by "; ". Times are ISO 8601 UTC
// ("2024-05-01T12:34:56.789Z"); numbers are the shortest text that parses back to the stored
// double; absent values are empty fields.
//
// JSON: one array of objects, one object per CSV row: run_json(run) (capture counters included)
// plus "calibration": calibration_json(...) or null, and "crosscheck": crosscheck_json(...) or
// null. NDJSON: the same objects, one per line, no array.
#include <cstddef>
#include <nlohmann/json.hpp>
#include <ostream>

#include "db/history/repository.hpp"

namespace imucal::db::history {

/// Run columns of the CSV export, in order.
extern const char* const kCsvRunColumns[24];
/// Calibration columns of the CSV export, in order (then parameters and sigmas).
extern const char* const kCsvCalibrationColumns[11];
/// The run's cross-check columns, after the sigmas (then the capture counters).
extern const char* const kCsvCrosscheckColumns[2];
/// The run's stored gap diagnosis (the JSON export's "diagnosis"), after the capture counters:
/// verdict, summary, explained_by ("|"-joined), best effect/magnitude/sigma/unit, overall gap and
/// p-value, held-out gap before/after.
extern const char* const kCsvDiagnosisColumns[11];

/// Write the CSV export; returns the number of data rows. IoError if the stream fails.
std::size_t export_csv(const Repository& repo, const ExportFilter& filter, std::ostream& out);
/// Write the JSON export (an array); returns the number of objects. IoError if the stream fails.
std::size_t export_json(const Repository& repo, const ExportFilter& filter, std::ostream& out);
/// Write the NDJSON export: the JSON export's objects, one per line (for tools that read a line at
/// a time); returns the number of objects. IoError if the stream fails.
std::size_t export_ndjson(const Repository& repo, const ExportFilter& filter, std::ostream& out);
/// The export in `format` ("csv", "json" or "ndjson"; InvalidInput otherwise).
std::size_t export_history(const Repository& repo, const ExportFilter& filter,
                           const std::string& format, std::ostream& out);

/// RFC 4180 field quoting (quotes only when needed).
std::string csv_field(const std::string& value);

// ----- JSON forms of the records -------------------------------------------------------------
/// {"run_id", "serial", "state", "verdict" (the run's: PASS/REVIEW/FAILED, or null while live),
///  "crosscheck_verdict" (the cross-check's own: PASS/REVIEW, or null), "started_at", "ended_at"
///  (or null), "started_at_ms", "ended_at_ms", "operator", "station", "sequence_name",
///  "sequence_sha256", "software_version", "archive_path", "archive_sha256", "failure_reason",
///  "reasons" (reasons_json), "reprocessed_from", ...}
nlohmann::json run_json(const RunRecord& run);
/// [{"source", "text"}, ...]: a run's reasons (RunReason).
nlohmann::json reasons_json(const std::vector<RunReason>& reasons);
/// {"method", "converged", "iterations", "runtime_s", "warnings",
///  "params": parameter-set JSON with "sigma" (ARCHITECTURE §3), "metrics": {...} or null}
nlohmann::json calibration_json(const CalibrationRecord& calibration);
/// {"verdict", "k_sigma", "failures": [{"term", "detail"}]}
nlohmann::json crosscheck_json(const CrosscheckRecord& crosscheck);
/// {"run": run_json, "calibrations": [...], "crosscheck": {...} or null}
nlohmann::json run_details_json(const RunDetails& details);
/// The active parameter set in the ARCHITECTURE §3 schema (five keys + "sigma") plus "source": the
/// run it comes from {run_id, serial, method, setting, station, started_at, verdict, [origin],
/// [promoted_at, promoted_by, promote_reason]}; db::archive::param_set_from_json / read_param_file
/// load it for the INS.
nlohmann::json active_params_json(const ActiveCalibration& active);

}  // namespace imucal::db::history
