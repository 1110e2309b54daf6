#pragma once
// Station signatures over a calibration history (issue #25): the period's AINS results read
// through db::history::FleetStats (a station's SQLite or the fleet store), the station errors'
// responses measured on the period's sequence with the truth simulator, and
// calib::studies::fleet::station_signatures — reported as JSON (what stationctl --json prints) and
// as text for QA, each flagged station with its likely cause, size ± σ, the advice and the runs it
// touches.
#include <functional>
#include <nlohmann/json.hpp>
#include <string>

#include "calib/studies/fleet/station_signature.hpp"
#include "db/history/fleet_stats.hpp"

namespace imucal::tools::report {

/// A bad signature window: which field ("since" or "until") and why.
struct WindowError : db::history::InvalidInput {
  WindowError(std::string field_name, std::string why)
      : db::history::InvalidInput(field_name + ": " + why),
        field(std::move(field_name)),
        reason(std::move(why)) {}
  std::string field, reason;
};

/// The period the signatures look at: `since` and `until` as given (UTC dates or times; a date
/// `until` means the end of that day), else the `default_days` days up to the end of the newest
/// run's day.
/// WindowError for unreadable text or a window that ends before it starts; no bounds at all when
/// the history holds no run.
db::history::FleetFilter signature_window(const db::history::Repository& history,
                                          const std::string& since, const std::string& until,
                                          int default_days = 7);

/// The signatures of the runs in `window` (every field of it applies). The responses are measured
/// on the sequence most of the runs followed (named in the report); a sequence the library does
/// not hold is db::history::InvalidInput naming it. `progress` gets a line before the slow steps.
nlohmann::json station_signature_report(
    const db::history::FleetStats& stats, const db::history::FleetFilter& window,
    const calib::studies::fleet::SignatureOptions& options,
    const std::function<void(const std::string&)>& progress = {});

/// The report as text: one line per station, and per flagged station its cause, advice and runs.
std::string render_signatures_text(const nlohmann::json& report);

/// Signatures period by period (a station drifting out of square between services shows as a
/// growing fit): `window` cut into consecutive periods of `period_days` ending at its end (the
/// first may reach before its start), each assessed on its own as station_signature_report does.
/// JSON {period_days, z_threshold, false_alarm, stations: [names], periods: [{since_ms, until_ms,
/// runs, stations: [{station, assessed, flagged, strongest: {effect, z, size, sigma, unit},
/// cause?}]}]}. db::history::InvalidInput for period_days outside 1..366.
nlohmann::json station_signature_trend(
    const db::history::FleetStats& stats, const db::history::FleetFilter& window, int period_days,
    const calib::studies::fleet::SignatureOptions& options,
    const std::function<void(const std::string&)>& progress = {});

/// The cell of `station` in one period of a trend (nullptr: no runs of it in that period).
const nlohmann::json* signature_trend_cell(const nlohmann::json& period,
                                           const std::string& station);

/// The trend as text: each station's strongest |z| per period ('*' flagged, '-' not assessed or no
/// runs), then each flagged station's causes period by period.
std::string render_signature_trend_text(const nlohmann::json& trend);

}  // namespace imucal::tools::report
