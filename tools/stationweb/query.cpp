// Query parameters and the checks every page shares.
#include "db/history/serial_number.hpp"
#include "tools/stationweb/html.hpp"
#include "tools/stationweb/list_filter.hpp"
#include "tools/stationweb/page_limits.hpp"
#include "tools/stationweb/page_util.hpp"
#include "tools/stationweb/pages.hpp"

namespace imucal::tools::stationweb {

std::string query_value(const Params& query, const std::string& name) {
  const auto range = query.equal_range(name);
  if (range.first == range.second) return "";
  if (std::next(range.first) != range.second) bad_input(name, "given more than once");
  return range.first->second;
}

void check_serial(const std::string& serial, const std::string& field) {
  if (const auto problem = db::history::serial_problem(serial)) bad_input(field, *problem);
}

std::string unit_search(const Params& query) {
  check_known_params(query, {"serial"});
  const std::string serial = trimmed(query_value(query, "serial"));  // a pasted " SN-0008 "
  if (serial.empty()) bad_input("serial", "no serial number given");
  check_serial(serial, "serial");
  return serial;
}

namespace {

/// A control character anywhere (before trimming: "qa-station%0A" is refused, not trimmed).
void check_no_control(const std::string& field, const std::string& text) {
  for (unsigned char c : text)
    if (c < 0x20 || c == 0x7F) bad_input(field, "has a control character");
}

std::optional<std::string> parse_setting_value(const Params& query,
                                               const std::optional<std::string>& fallback) {
  const std::string raw = query_value(query, "setting");
  check_no_control("setting", raw);
  const std::string setting = trimmed(raw);
  if (setting.empty()) return fallback;
  if (setting == "all") return std::nullopt;
  if (setting != "factory" && setting != "land" && setting != "sea")
    bad_input("setting",
              "\"" + setting.substr(0, 40) + "\" is not a setting: factory, land, sea or all");
  return setting;
}

std::optional<std::string> parse_verdict_value(const Params& query) {
  const std::string raw = query_value(query, "verdict");
  check_no_control("verdict", raw);
  if (trimmed(raw).empty() || trimmed(raw) == "all") return std::nullopt;
  std::string list;
  for (const std::string& word : db::history::verdict_list(raw)) {
    if (word != "live") {
      try {
        db::history::run_verdict_from_string(word);
      } catch (const db::history::DbError&) {
        bad_input("verdict", "\"" + word.substr(0, 40) +
                                 "\" is not a verdict: PASS, REVIEW, FAILED, STATION-FAULT, "
                                 "ABORTED, INTERRUPTED or live (several: comma-separated; all: "
                                 "every verdict)");
      }
    }
    if (("," + list + ",").find("," + word + ",") == std::string::npos)
      list += (list.empty() ? "" : ",") + word;
  }
  if (list.empty()) bad_input("verdict", "no verdict given between the commas");
  return list;
}

}  // namespace

ListFilter parse_list_filter(const History& history, const Params& query,
                             const std::optional<std::string>& setting_default,
                             bool default_window) {
  ListFilter l;
  db::history::FleetFilter& f = l.filter;
  const std::string since = trimmed(query_value(query, "since"));
  const std::string until = trimmed(query_value(query, "until"));
  if (!since.empty()) f.since_ms = window_time("since", since, false, l.notes);
  if (!until.empty()) f.until_ms = window_time("until", until, true, l.notes);
  if (f.since_ms && f.until_ms && *f.since_ms >= *f.until_ms)
    bad_input("until",
              "the window is empty: until (" + until + ") is not after since (" + since + ")");
  const std::string station_raw = query_value(query, "station");
  check_no_control("station", station_raw);
  if (const std::string station = trimmed(station_raw); !station.empty()) f.station = station;
  f.setting = parse_setting_value(query, setting_default);
  f.verdict = parse_verdict_value(query);
  const std::string serial = trimmed(query_value(query, "serial"));
  if (!serial.empty()) {
    check_serial(serial, "serial");
    f.serial = serial;
  }
  try {
    db::history::validate_filter(f);
  } catch (const db::history::InvalidInput& e) {
    bad_input("station", e.what());  // the only rule left unchecked above: its length
  }
  if (f.station) check_known_station(history, *f.station);  // #52: not "no runs"
  if (f.serial) check_known_serial(history, *f.serial, "serial");
  if (!f.since_ms && !f.until_ms && default_window) {
    const std::vector<db::history::RunRecord> newest = history.repo->recent_runs(1);
    if (!newest.empty()) {
      f.until_ms = (db::history::utc_day(newest.front().started_at_ms) + 1) * kDayMs;
      f.since_ms = *f.until_ms - kDefaultWindowDays * kDayMs;
      l.default_window = true;
    }
  }
  return l;
}

std::string window_text(const db::history::FleetFilter& f) {
  std::string s = f.since_ms ? "from " + window_time_text(*f.since_ms) + " UTC " : "at any time ";
  s +=
      f.until_ms ? "until (before) " + window_time_text(*f.until_ms) + " UTC" : "to the newest run";
  return s;
}

std::string window_query(const db::history::FleetFilter& f) {
  std::string s;
  if (f.since_ms) s += "&since=" + url_encode(db::history::format_time_utc(*f.since_ms));
  if (f.until_ms) s += "&until=" + url_encode(db::history::format_time_utc(*f.until_ms));
  return s;
}

}  // namespace imucal::tools::stationweb
