// "/runs": the runs behind an aggregate (issue #52 item 8) — a fleet bar (station, day), a verdict
// count (station, verdict, window), a distribution (station, param, window) — with the same
// filters as the fleet pages, listed with `stationctl history`'s columns (run_table) and, for a
// parameter, its AINS value. ?format=csv|json gives the list as data.
//
//   station, serial   exact; an unknown one is 404 saying so
//   verdict           PASS, REVIEW, FAILED, STATION-FAULT, ABORTED, INTERRUPTED, comma-separated
//   setting           factory, land or sea (default: every setting)
//   since, until      YYYY-MM-DD (until includes that day) or ISO times; without since (and no
//                     serial) the 30 days up to the newest run's day
//   param             a parameter-set name: only runs with an AINS value of it, the value shown
//   limit             1..2000 rows shown (default 500), newest first; the count says how many match
#include <algorithm>
#include <cctype>
#include <set>

#include "calib/core/calibration_input.hpp"
#include "calib/core/param_set.hpp"
#include "db/history/fleet_stats.hpp"
#include "tools/stationweb/html.hpp"
#include "tools/stationweb/page_util.hpp"
#include "tools/stationweb/pages.hpp"
#include "tools/stationweb/run_table.hpp"

namespace imucal::tools::stationweb {

namespace {

constexpr std::size_t kRunsDefaultLimit = 500, kRunsMaxLimit = 2000;
constexpr std::int64_t kRunsDefaultDays = 30;

struct RunsQuery {
  db::history::ExportFilter filter;  ///< serial, since, station
  std::optional<db::history::TimestampMs> until_ms;
  std::set<std::string> verdicts;  ///< empty: every verdict
  std::optional<calib::core::Setting> setting;
  int param = -1;  ///< parameter index, -1: none
  std::size_t limit = kRunsDefaultLimit;
  bool default_window = false;
};

db::history::TimestampMs time_field(const std::string& field, const std::string& text,
                                    bool end_of_day) {
  try {
    if (text.size() == 10)
      return db::history::parse_time_utc(text + "T00:00:00Z") + (end_of_day ? kDayMs : 0);
    return db::history::parse_time_utc(text);
  } catch (const std::exception&) {
    bad_input(field, "\"" + text.substr(0, 40) + "\" is not a date (YYYY-MM-DD) or ISO time");
  }
}

std::set<std::string> verdict_set(const std::string& text) {
  std::set<std::string> out;
  for (std::size_t p = 0; p <= text.size() && !text.empty();) {
    const std::size_t q = std::min(text.find(',', p), text.size());
    const std::string word = trimmed(text.substr(p, q - p));
    try {
      out.insert(db::history::to_string(db::history::run_verdict_from_string(word)));
    } catch (const db::history::DbError&) {
      bad_input("verdict", "\"" + word.substr(0, 40) +
                               "\" is not a verdict: PASS, REVIEW, FAILED, STATION-FAULT, "
                               "ABORTED or INTERRUPTED (several: comma-separated)");
    }
    p = q + 1;
  }
  return out;
}

RunsQuery parse_runs_query(const History& history, const Params& query) {
  RunsQuery q;
  const std::string station = trimmed(query_value(query, "station"));
  const std::string serial = trimmed(query_value(query, "serial"));
  if (!serial.empty()) {
    check_serial(serial, "serial");
    check_known_serial(history, serial, "serial");
    q.filter.serial = serial;
  }
  if (!station.empty()) {
    check_known_station(history, station);
    q.filter.station = station;
  }
  q.verdicts = verdict_set(query_value(query, "verdict"));
  const std::string setting = query_value(query, "setting");
  if (!setting.empty() && !(q.setting = calib::core::parse_setting(setting)))
    bad_input("setting",
              "\"" + setting.substr(0, 40) + "\" is not a setting: factory, land or sea");
  const std::string since = query_value(query, "since"), until = query_value(query, "until");
  if (!since.empty()) q.filter.since_ms = time_field("since", since, false);
  if (!until.empty()) q.until_ms = time_field("until", until, true);
  if (q.filter.since_ms && q.until_ms && *q.filter.since_ms >= *q.until_ms)
    bad_input("until", "the window ends (" + until + ") before it starts (" + since + ")");
  if (const std::string param = query_value(query, "param"); !param.empty()) {
    try {
      q.param = db::history::param_index(param);
    } catch (const db::history::InvalidInput& e) {
      bad_input("param", e.what());
    }
  }
  const std::string limit = query_value(query, "limit");
  if (!limit.empty()) {
    bool digits = limit.size() <= 5;
    for (char c : limit) digits = digits && std::isdigit(static_cast<unsigned char>(c));
    q.limit = digits ? std::stoul(limit) : 0;
    if (q.limit < 1 || q.limit > kRunsMaxLimit)
      bad_input("limit", "\"" + limit.substr(0, 40) + "\" is not a whole number from 1 to " +
                             std::to_string(kRunsMaxLimit));
  }
  return q;
}

/// A bounded read: without since and serial, the 30 days up to the newest run's day.
void default_window(const History& history, RunsQuery& q) {
  if (q.filter.since_ms || q.filter.serial) return;
  const auto newest = history.repo->recent_runs(1);
  if (newest.empty()) return;
  const std::int64_t day =
      db::history::utc_day(q.until_ms ? *q.until_ms - 1 : newest[0].started_at_ms);
  q.filter.since_ms = (day + 1 - kRunsDefaultDays) * kDayMs;
  q.default_window = true;
}

struct Listed {
  std::vector<db::history::RunRecord> runs;  ///< newest first, at most limit
  std::vector<double> value_si;              ///< the parameter's AINS value per listed run
  std::size_t matched = 0;                   ///< every run the filters take
};

struct PastUntil {};  ///< ends the time-ordered export once it passes the window

Listed list_runs(const History& history, const RunsQuery& q) {
  std::vector<std::pair<db::history::RunRecord, double>> all;
  std::set<db::history::RunId> seen;
  auto keep = [&](const db::history::RunRecord& r) {
    if (!q.verdicts.empty() &&
        (!r.verdict || !q.verdicts.count(db::history::to_string(*r.verdict))))
      return false;
    return !q.setting || r.setting == *q.setting;
  };
  try {
    history.repo->export_rows(q.filter, [&](const db::history::ExportRow& row) {
      if (q.until_ms && row.run.started_at_ms >= *q.until_ms) {
        if (q.filter.since_ms) throw PastUntil{};  // ordered by time: nothing later matches
        return;
      }
      if (!keep(row.run)) return;
      if (q.param < 0) {
        if (seen.insert(row.run.run_id).second) all.push_back({row.run, 0.0});
        return;
      }
      const auto& c = row.calibration;
      if (!c || c->method != db::history::Method::kAins) return;
      if (listed(c->unobservable, calib::core::param_info(q.param).name)) return;
      if (seen.insert(row.run.run_id).second)
        all.push_back({row.run, c->params.to_vector()(q.param)});
    });
  } catch (const PastUntil&) {
  }
  std::stable_sort(all.begin(), all.end(), [](const auto& a, const auto& b) {
    return a.first.started_at_ms > b.first.started_at_ms ||
           (a.first.started_at_ms == b.first.started_at_ms && a.first.run_id > b.first.run_id);
  });
  Listed out;
  out.matched = all.size();
  for (std::size_t i = 0; i < all.size() && i < q.limit; ++i) {
    out.runs.push_back(all[i].first);
    out.value_si.push_back(all[i].second);
  }
  return out;
}

/// The filters as a sentence, each value as given.
std::string filters_line(const RunsQuery& q, const Params& query) {
  std::string s;
  for (const char* name : {"station", "serial", "verdict", "setting", "param"}) {
    const std::string v = query_value(query, name);
    if (!v.empty()) s += std::string(s.empty() ? "" : ", ") + name + " " + esc(v);
  }
  s += std::string(s.empty() ? "" : ", ") +
       (q.filter.since_ms ? "from " + short_time(*q.filter.since_ms) + " UTC" : "from the start") +
       (q.until_ms ? " until (before) " + short_time(*q.until_ms) + " UTC" : " to the newest run");
  if (q.default_window) s += " (the default window: 30 days up to the newest run's day)";
  return s;
}

}  // namespace

Reply runs_reply(const History& history, const Params& query) {
  check_known_params(query, {"station", "serial", "verdict", "setting", "since", "until", "param",
                             "limit", "format"});
  const Format format = parse_format(query);
  RunsQuery q = parse_runs_query(history, query);
  default_window(history, q);
  const Listed l = list_runs(history, q);
  std::string header;
  std::vector<std::string> cells, values;
  if (q.param >= 0) {
    const calib::core::ParamInfo& info = calib::core::param_info(q.param);
    header = info.name + " [" + info.human_unit + "]";
    for (double v : l.value_si) {
      cells.push_back("<span data-value-si='" + exact(v) + "'>" +
                      fmt("%.6g", v * info.si_to_human) + "</span>");
      values.push_back(fmt("%.17g", v * info.si_to_human));
    }
  }
  if (format == Format::kJson)
    return {run_list_json("", l.runs, l.matched), "application/json", "runs.json"};
  if (format == Format::kCsv)
    return {run_list_csv(l.runs, header, values), "text/csv; charset=utf-8", "runs.csv"};
  std::string target = "/runs?";
  for (const auto& [k, v] : query)
    if (k != "format") target += (target.back() == '?' ? "" : "&") + k + "=" + url_encode(v);
  std::string b = "<h1>Runs</h1>\n<p id='runs-filters'>" + filters_line(q, query) + "</p>\n";
  b += "<p><span id='runs-matched' data-value='" + std::to_string(l.matched) + "'>" +
       std::to_string(l.matched) + "</span> run" + (l.matched == 1 ? "" : "s") + " match" +
       (l.matched == 1 ? "es" : "") +
       (l.matched > l.runs.size() ? "; the newest " + std::to_string(l.runs.size()) +
                                        " shown (limit=" + std::to_string(q.limit) + ")"
                                  : "") +
       ".</p>\n";
  b += request_form("/runs", query, "Filters (the same as the fleet pages'):");
  if (l.runs.empty()) return {page("Runs", b + "<p>No run matches.</p>\n")};
  b += run_table(l.runs, true, "runs", esc(header), cells) + download_links(target);
  return {page("Runs", b)};
}

}  // namespace imucal::tools::stationweb
