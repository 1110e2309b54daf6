#pragma once
// What the read commands of the control socket return, and how stationctl prints it for people.
//
// One path for both transports: the daemon's control server answers history/show/params/export
// with answer_repository_read() on its repository, and stationctl, when the daemon is down, calls
// the very same function on a read-only database. The text renderings take the *result JSON*
// (never the records), so `stationctl show 7` prints the same bytes whichever way it got the
// answer.
//
// Result shapes ("--json" prints exactly these):
//   history  {"serial": SN, "runs": [run, ...], "total": N}  newest first; without a serial
//            "serial" is null and the runs are every unit's newest (kAllUnitsHistoryLimit)
//   show     {"run": run, "calibrations": [calibration, ...], "crosscheck": {...} | null}
//   params   the ARCHITECTURE §3 parameter-set JSON with "sigma" (db::archive::read_param_file
//   loads it) export   {"format": "csv"|"json", "rows": N, "content": "<the whole export as text>"}
// where run = db::history::run_json(record) (with "capture": the run's capture counters,
// CaptureStats JSON with "complete", or null), and calibration = db::history::calibration_json
// (params + sigma as the parameter-set JSON, metrics or null).
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "db/history/repository.hpp"
#include "station/control/control_protocol.hpp"

namespace imucal::station::control {

// ----- JSON shapes ------------------------------------------------------------------------------
/// db::history::run_json(run), which includes "capture" (RunRecord::capture_json parsed; null when
/// empty; db::history::Corrupt naming the run if the stored text is not a JSON object).
nlohmann::json run_record_json(const db::history::RunRecord& run);
/// `total`: how many runs the serial has in all (runs may be the newest few of them).
nlohmann::json history_result(const std::string& serial,
                              const std::vector<db::history::RunRecord>& runs, std::size_t total);
nlohmann::json show_result(const db::history::RunDetails& details);
/// Exactly the parameter-set JSON of the active set (its run's holding method's: AINS but where
/// legacy holds a land run) with "sigma".
nlohmann::json params_result(const db::history::ActiveCalibration& active);
/// format "csv", "json" or "ndjson" (db::history::InvalidInput otherwise), a row per run and
/// method or, `per_run`, per run (db/history/export_per_run.hpp); the whole export in "content".
nlohmann::json export_result(const db::history::Repository& repo,
                             const db::history::ExportFilter& filter, const std::string& format,
                             bool per_run = false);
/// The filter of an export request's validated args (serial, since): db::history::NotFound for a
/// serial with no runs (its export would silently be empty).
db::history::ExportFilter export_filter(const db::history::Repository& repo,
                                        const nlohmann::json& args);

/// `history` without a serial: every unit's newest runs, this many unless args.limit says.
inline constexpr std::size_t kAllUnitsHistoryLimit = 20;

/// Answers a validated history/show/params/export request from `repo`. Throws db::history::DbError
/// (the server maps its kind with error_code_for) or std::invalid_argument for another command.
nlohmann::json answer_repository_read(const db::history::Repository& repo, const Request& request);

// ----- Text for people --------------------------------------------------------------------------
/// A table: run, started (UTC), state, verdict, sequence, operator, duration, reason.
std::string render_history_text(const nlohmann::json& history);
/// The run report: identity, times, archive, capture counters, both calibrations side by side in
/// human units (calib::core::param_info: µg, ppm, µrad, deg/h, arcsec) with 1-σ, metrics,
/// cross-check.
std::string render_show_text(const nlohmann::json& show);
/// The parameter-set JSON, pretty-printed (what an INS loads); ends in '\n'.
std::string render_params_text(const nlohmann::json& params);
/// The history's SLOT cell: the fixture slot and the table run it shared with its siblings
/// ("B of 12"), or "-" on a one-unit station.
std::string slot_cell(const nlohmann::json& run);
/// One short cell for a run's stored gap diagnosis: "-" (none), "consistent", the best effect with
/// its magnitude ("gyro_g_sensitivity 0.04±0.004 deg/h/g"), or the ambiguous names joined by "|".
std::string gap_cell(const nlohmann::json& run);
/// The daemon status (ControlHandler::status without run id) or {"run": {...}} (with one).
std::string render_status_text(const nlohmann::json& status);
/// One line for a live run: "run 7 SIM-0001: step 3/18 resting, 12 s left" (no '\n').
std::string progress_line(const nlohmann::json& run);
/// One line for a finished run: "run 7 SIM-0001: done, verdict PASS" (+ reason), no '\n'.
std::string outcome_line(const nlohmann::json& run);
/// "12 s", "3 min 05 s", "1 h 02 min".
std::string format_duration_s(double seconds);

}  // namespace imucal::station::control
