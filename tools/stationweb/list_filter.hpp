#pragma once
// The filters /fleet and /runs share (issue #52, the audit's F4 and F11): one parser for both, so
// a fleet figure's link lists what the figure counts. Implemented in query.cpp.
//
//   station   trimmed; a control character or more than 200 bytes is 400, an unknown one 404
//   serial    trimmed, the serial rule (400), an unknown one 404
//   setting   factory, land, sea or all (every setting); absent: the page's default
//   verdict   PASS, REVIEW, FAILED, STATION-FAULT, ABORTED, INTERRUPTED or live, one or several
//             comma-separated (each trimmed), or all (every verdict, as absent)
//   since, until  YYYY-MM-DD (until includes that day) or ISO times, clamped to the served dates
//             with a note (page_limits.hpp); one given leaves the other side open (a lone until:
//             any time until); neither: the 30 days up to the newest run's day
#include <optional>
#include <string>

#include "db/history/fleet_stats.hpp"
#include "tools/stationweb/history_source.hpp"
#include "tools/stationweb/pages.hpp"

namespace imucal::tools::stationweb {

inline constexpr int kDefaultWindowDays = 30;

struct ListFilter {
  db::history::FleetFilter filter;  ///< what the page counts or lists
  bool default_window = false;      ///< neither since nor until: the 30 days up to the newest day
  std::string notes;                ///< dates clamped to the served range, said on the page
};

/// Every filter of the file comment. `setting_default`: the setting when none is given ("factory"
/// on /fleet, every setting on /runs). `default_window`: whether no since/until means the default
/// window (false: every time, /runs' list of one serial).
ListFilter parse_list_filter(const History& history, const Params& query,
                             const std::optional<std::string>& setting_default,
                             bool default_window = true);

/// "from 2026-11-01 00:00:00 UTC until (before) 2026-12-01 00:00:00 UTC", "at any time until …",
/// "from … to the newest run": the window as both pages print it.
std::string window_text(const db::history::FleetFilter& filter);

/// The window as since/until query texts that give it back exactly (ISO times; "" for an open
/// side): the fleet page's links carry the window the figure counted.
std::string window_query(const db::history::FleetFilter& filter);

}  // namespace imucal::tools::stationweb
