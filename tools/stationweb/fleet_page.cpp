// "/fleet": the history's aggregates per station through db::history::FleetStats — runs per station
// per UTC day, verdict counts and rates per station, and one AINS parameter's distribution per
// station — for a window (since/until; default: the 30 days up to the newest run) and optional
// station and serial filters.
#include <algorithm>
#include <cmath>
#include <map>
#include <nlohmann/json.hpp>
#include <set>

#include "calib/core/param_set.hpp"
#include "tools/stationweb/fleet_svg.hpp"
#include "tools/stationweb/html.hpp"
#include "tools/stationweb/list_filter.hpp"
#include "tools/stationweb/page_limits.hpp"
#include "tools/stationweb/page_util.hpp"
#include "tools/stationweb/pages.hpp"
#include "tools/stationweb/run_table.hpp"

namespace imucal::tools::stationweb {

namespace {

struct FleetQuery {
  db::history::FleetFilter filter;
  std::optional<int> param;
  Params echo;  ///< the form's values as given
  bool default_window = false;
  std::string notes;  ///< dates clamped to the served range (page_limits.hpp)
};

/// The filters /runs shares (list_filter.hpp: setting default factory — a field run's values are
/// another population; "all" for every setting), and the parameter.
FleetQuery parse_query(const History& history, const Params& query) {
  FleetQuery q;
  for (const char* name : {"since", "until", "station", "serial", "param", "setting", "verdict"})
    q.echo.emplace(name, query_value(query, name));
  ListFilter l = parse_list_filter(history, query, std::string("factory"));
  q.filter = l.filter;
  q.default_window = l.default_window;
  q.notes = l.notes;
  const std::string param = trimmed(q.echo.find("param")->second);
  if (!param.empty()) {
    try {
      q.param = db::history::param_index(param);
    } catch (const db::history::InvalidInput& e) {
      bad_input("param", e.what());
    }
  }
  return q;
}

/// <label>NAME <select>: the options, `given` selected; `none` (if not "") first as value ''.
std::string choice(const char* name, const std::string& given,
                   const std::vector<std::string>& options, const char* none) {
  std::string s = std::string("<label>") + name + " <select name='" + name + "'>";
  if (*none) s += std::string("<option value=''>") + none + "</option>";
  bool listed_option = given.empty();
  for (const std::string& o : options) {
    s += "<option" + std::string(given == o ? " selected" : "") + ">" + o + "</option>";
    listed_option = listed_option || given == o;
  }
  // A value the list does not offer (verdict=PASS,REVIEW) stays what the form sends again.
  if (!listed_option) s += "<option selected>" + esc(given) + "</option>";
  return s + "</select></label>";
}

std::string filter_form(const FleetQuery& q) {
  auto value = [&](const char* name) { return esc(q.echo.find(name)->second); };
  std::string s = "<form class='filters' id='fleet-filters' action='/fleet' method='get'>\n";
  s += "<label>since <input name='since' size='12' placeholder='YYYY-MM-DD' value='" +
       value("since") + "'></label>";
  s += "<label>until <input name='until' size='12' placeholder='YYYY-MM-DD' value='" +
       value("until") + "'></label>";
  s += "<label>station <input name='station' size='14' value='" + value("station") + "'></label>";
  s += "<label>serial <input name='serial' size='14' value='" + value("serial") + "'></label>";
  s += "<label>parameter <select name='param'><option value=''>(none)</option>";
  for (int i = 0; i < calib::core::ParamSet::kSize; ++i) {
    const std::string& name = calib::core::param_info(i).name;
    s += "<option" + std::string(q.param && *q.param == i ? " selected" : "") + ">" + name +
         "</option>";
  }
  s += "</select></label>";
  s += choice("setting",
              q.echo.find("setting")->second.empty() ? "factory" : q.echo.find("setting")->second,
              {"factory", "land", "sea", "all"}, "");
  s += choice("verdict", q.echo.find("verdict")->second,
              {"PASS", "REVIEW", "FAILED", "STATION-FAULT", "ABORTED", "INTERRUPTED", "live"},
              "(every verdict)");
  return s + " <button type='submit'>Show</button></form>\n";
}

std::string window_line(const FleetQuery& q) {
  const auto& f = q.filter;
  std::string s = "<p id='window' data-since-ms='" +
                  (f.since_ms ? std::to_string(*f.since_ms) : "") + "' data-until-ms='" +
                  (f.until_ms ? std::to_string(*f.until_ms) : "") + "' data-setting='" +
                  esc(f.setting.value_or("")) + "' data-verdict='" + esc(f.verdict.value_or("")) +
                  "'>Runs started " + window_text(f);
  if (q.default_window)
    s += " — the " + std::to_string(kDefaultWindowDays) +
         " days up to the newest run's day (set since/until for another window)";
  if (f.station) s += ", station " + esc(*f.station);
  if (f.serial) s += ", serial " + unit_link(*f.serial);
  s += f.setting ? ", " + esc(*f.setting) + " runs" +
                       (*f.setting == "factory" && q.echo.find("setting")->second.empty()
                            ? " (the default: setting=all for field runs too)"
                            : "")
                 : ", every setting";
  if (f.verdict) s += ", verdict " + esc(*f.verdict);
  s += ". <span id='capture-rule'>One capture counts once: a reprocessed run is stood for by its "
       "newest reprocess.</span>";
  if (!q.notes.empty()) s += " <span id='window-note' class='REVIEW'>" + esc(q.notes) + "</span>";
  return s + "</p>\n";
}

/// The day range the chart spans: the window, narrowed to the days that have runs.
void chart_days(const FleetQuery& q, const std::vector<db::history::StationDayCount>& counts,
                std::int64_t& first, std::int64_t& last) {
  std::int64_t lo = counts.front().day, hi = lo;
  for (const auto& c : counts) lo = std::min(lo, c.day), hi = std::max(hi, c.day);
  first = q.filter.since_ms ? db::history::utc_day(*q.filter.since_ms) : lo;
  last = q.filter.until_ms ? db::history::utc_day(*q.filter.until_ms - 1) : hi;
  if (last - first > 3 * 366) first = std::max(first, lo), last = std::min(last, hi);
}

std::string runs_chart_section(const FleetQuery& q,
                               const std::vector<db::history::StationDayCount>& counts,
                               const std::vector<std::string>& stations) {
  std::string s = "<h2>Runs per station per day</h2>\n";
  if (counts.empty()) return s + "<p>No runs in this window.</p>\n";
  std::int64_t first = 0, last = 0;
  chart_days(q, counts, first, last);
  return s + runs_chart(counts, stations, first, last) +
         "<p class='muted'>The numbers: <a href='#runs-per-day'>the table below</a>.</p>\n";
}

/// What a link to the runs behind a figure adds to the page's filters.
struct Behind {
  std::optional<std::string> verdict;  ///< the figure's verdict (within the page's verdicts)
  std::optional<std::int64_t> day;     ///< the figure's UTC day (within the page's window)
  std::string param;                   ///< the distribution's parameter
};

/// The runs behind a fleet figure (issue #52 item 8, the audit's F1): /runs with every filter the
/// figure counted — station, serial, setting (`all` when every setting), verdicts, the window as
/// exact times (the default window too) — and the figure's own (a verdict, a day, a parameter).
/// /runs counts as the fleet does (one capture once), so the list holds as many runs as the
/// figure says. "" when the figure's verdict is not among the page's (it counts nothing).
std::string runs_href(const FleetQuery& q, const std::string& station, const Behind& behind) {
  const auto& f = q.filter;
  std::string href = "/runs?station=" + url_encode(station);
  if (f.serial) href += "&serial=" + url_encode(*f.serial);
  href += "&setting=" + url_encode(f.setting.value_or("all"));
  std::optional<std::string> verdict = f.verdict;
  if (behind.verdict) {
    if (f.verdict && !listed(db::history::verdict_list(*f.verdict), *behind.verdict)) return "";
    verdict = behind.verdict;
  }
  if (verdict) href += "&verdict=" + url_encode(*verdict);
  if (behind.day) {  // the day, within the page's window
    const std::int64_t start = *behind.day * kDayMs, end = start + kDayMs;
    if ((!f.since_ms || *f.since_ms <= start) && (!f.until_ms || *f.until_ms >= end)) {
      href += "&since=" + day_text(*behind.day) + "&until=" + day_text(*behind.day);
    } else {
      db::history::FleetFilter window;
      window.since_ms = f.since_ms ? std::max(*f.since_ms, start) : start;
      window.until_ms = f.until_ms ? std::min(*f.until_ms, end) : end;
      href += window_query(window);
    }
  } else if (q.default_window) {  // the default window's days, so the list needs no default
    href += "&since=" + day_text(db::history::utc_day(*f.since_ms)) +
            "&until=" + day_text(db::history::utc_day(*f.until_ms - 1));
  } else {  // the texts given: /runs reads them with the same parser (list_filter.hpp)
    for (const char* w : {"since", "until"})
      if (const std::string v = trimmed(q.echo.find(w)->second); !v.empty())
        href += std::string("&") + w + "=" + url_encode(v);
  }
  if (!behind.param.empty()) href += "&param=" + url_encode(behind.param);
  return href;
}

std::string runs_link(const FleetQuery& q, const std::string& station, const Behind& behind,
                      const std::string& text) {
  const std::string href = runs_href(q, station, behind);
  if (href.empty()) return text;
  return "<a class='runs-link' href='" + esc(href) + "'>" + text + "</a>";
}

std::string runs_table_section(const FleetQuery& q,
                               const std::vector<db::history::StationDayCount>& counts,
                               const std::vector<std::string>& stations) {
  std::string s = "<h2>Runs per station per day (table)</h2>\n";
  if (counts.empty()) return s + "<p id='runs-per-day'>No runs in this window.</p>\n";
  std::map<std::int64_t, std::map<std::string, std::int64_t>> by_day;
  for (const auto& c : counts) by_day[c.day][c.station] = c.runs;
  s += "<table id='runs-per-day'>\n<tr><th>day (UTC)</th>";
  for (const auto& st : stations) s += "<th class='num'>" + esc(st) + "</th>";
  s += "<th class='num'>all</th></tr>\n";
  for (const auto& [day, row] : by_day) {
    std::int64_t total = 0;
    s += "<tr><td>" + day_text(day) + "</td>";
    for (const auto& st : stations) {
      const auto it = row.find(st);
      const std::int64_t n = it == row.end() ? 0 : it->second;
      total += n;
      s += "<td class='num' data-station='" + esc(st) + "' data-day='" + day_text(day) +
           "' data-runs='" + std::to_string(n) + "'>" +
           (n ? runs_link(q, st, Behind{std::nullopt, day, ""}, std::to_string(n)) : "") + "</td>";
    }
    s += "<td class='num'>" + std::to_string(total) + "</td></tr>\n";
  }
  return s + "</table>\n";
}

std::string share(std::int64_t n, std::int64_t total) {
  return std::to_string(n) + " <span class='muted'>(" +
         fmt("%.1f", total ? 100.0 * static_cast<double>(n) / static_cast<double>(total) : 0.0) +
         " %)</span>";
}

/// The verdicts per station (issue #50): PASS, REVIEW and FAILED as shares of the runs whose
/// outcome was the unit's own — its yield — and the station's faults, aborts (an operator's or the
/// daemon's stop) and interrupted runs counted apart, per station, never against the units.
std::string verdict_section(const FleetQuery& q,
                            const std::vector<db::history::StationVerdictCounts>& verdicts) {
  std::string s = "<h2>Verdicts per station</h2>\n";
  if (verdicts.empty()) return s + "<p id='verdicts'>No runs in this window.</p>\n";
  s += verdict_chart(verdicts);
  s += "<p class='muted'>The chart counts runs; the table gives PASS, REVIEW and FAILED as shares "
       "of the runs the units decided (their yield: the one PASS rate on this page); station "
       "faults (table, CAN bus, disk), aborts (an operator's, or the station daemon stopped during "
       "the run) and interrupted runs are the station's and the operators', not the units'.</p>\n";
  s += "<table id='verdicts'>\n<tr><th>station</th><th class='num'>PASS</th><th "
       "class='num'>REVIEW</th><th class='num'>FAILED</th><th class='num'>station faults</th>"
       "<th class='num'>aborted</th><th class='num'>interrupted</th><th class='num'>live</th><th "
       "class='num'>runs</th></tr>\n";
  for (const auto& v : verdicts) {
    const std::int64_t own = v.unit_outcomes();
    const auto attr = [](const char* name, std::int64_t n) {
      return std::string(" data-") + name + "='" + std::to_string(n) + "'";
    };
    const auto cell = [](const std::string& text) { return "<td class='num'>" + text + "</td>"; };
    s += "<tr data-station='" + esc(v.station) + "'" + attr("pass", v.pass) +
         attr("review", v.review) + attr("failed", v.failed) +
         attr("station-fault", v.station_fault) + attr("aborted", v.aborted) +
         attr("interrupted", v.interrupted) + attr("live", v.live) + attr("unit-outcomes", own) +
         attr("total", v.total()) + "><td>" + esc(v.station) + "</td>";
    const auto linked = [&](const char* verdict, const std::string& text) {
      return cell(runs_link(q, v.station, Behind{std::string(verdict), std::nullopt, ""}, text));
    };
    s += linked("PASS", share(v.pass, own)) + linked("REVIEW", share(v.review, own)) +
         linked("FAILED", share(v.failed, own)) +
         linked("STATION-FAULT", std::to_string(v.station_fault)) +
         linked("ABORTED", std::to_string(v.aborted)) +
         linked("INTERRUPTED", std::to_string(v.interrupted)) +
         linked("live", std::to_string(v.live)) +
         cell(runs_link(q, v.station, Behind{}, std::to_string(v.total()))) + "</tr>\n";
  }
  return s + "</table>\n";
}

std::string distribution_row(const FleetQuery& q, const db::history::ParamSummary& d,
                             const calib::core::ParamInfo& info) {
  const double k = info.si_to_human;
  std::string s = "<tr data-station='" + esc(d.station) + "' data-count='" +
                  std::to_string(d.count) + "' data-other-frame='" + std::to_string(d.other_frame) +
                  "'";
  const std::pair<const char*, double> stats[] = {
      {"mean", d.mean},     {"std", d.std_dev}, {"min", d.min}, {"q1", d.q1},
      {"median", d.median}, {"q3", d.q3},       {"max", d.max}};
  for (const auto& [name, v] : stats) s += std::string(" data-") + name + "='" + exact(v) + "'";
  s += "><td>" + esc(d.station) + "</td><td class='num'>" +
       runs_link(q, d.station, Behind{std::nullopt, std::nullopt, info.name},
                 std::to_string(d.count)) +
       "</td>";
  // Each figure to the precision the spread allows: the mean to its standard error, the
  // order statistics and the std to the std's second digit (issue #52 item 12).
  const double spread = d.std_dev * k;
  const double mean_se = d.count > 1 ? spread / std::sqrt(static_cast<double>(d.count)) : 0.0;
  for (const auto& [name, v] : stats) {
    const std::string text = d.count == 0                  ? std::string("—")  // all left out
                             : std::string(name) == "mean" ? fmt_to_sigma(v * k, mean_se)
                             : std::string(name) == "std"  ? fmt_sigma(v * k)
                                                           : fmt_to_sigma(v * k, spread);
    s += "<td class='num'>" + text + "</td>";
  }
  if (db::history::frame_dependent(*q.param))
    s += "<td class='num other-frame'>" + std::to_string(d.other_frame) + "</td>";
  return s + "</tr>\n";
}

std::string distribution_section(const FleetQuery& q,
                                 const std::vector<db::history::ParamSummary>& dist) {
  std::string s = "<h2>Parameter distribution per station</h2>\n";
  if (!q.param) return s + "<p>Choose a parameter above to see its distribution per station.</p>\n";
  const calib::core::ParamInfo& info = calib::core::param_info(*q.param);
  s += "<p>" + info.name + ": the AINS value of every run counted above that has one, in " +
       esc(info.human_unit) + " (sample standard deviation; quartiles interpolated).</p>\n";
  if (dist.empty()) return s + "<p id='distribution'>No AINS calibration in this window.</p>\n";
  const bool by_frame = db::history::frame_dependent(*q.param);
  std::int64_t other_frame = 0;
  for (const auto& d : dist) other_frame += d.other_frame;
  if (by_frame)
    s += "<p id='frame-note' data-other-frame='" + std::to_string(other_frame) + "'>" + info.name +
         " depends on the body frame a result is expressed in: only results in the housing "
         "frame (factory runs) are counted. " +
         (other_frame ? count_of(other_frame, "result") +
                            " left out (last column): field runs' results are in the "
                            "accelerometer-symmetric frame, their misalignments relative to the "
                            "accelerometer triad, not to the housing, and cannot be pooled with "
                            "the factory runs' (compare them on a unit's page or /compare)."
                      : std::string("No result was left out.")) +
         "</p>\n";
  std::vector<db::history::ParamSummary> shown;
  for (const auto& d : dist)
    if (d.count > 0) shown.push_back(d);
  s += box_plot(shown, info);
  s += "<table id='distribution' data-param='" + info.name + "' data-unit='" +
       esc(info.human_unit) + "'>\n<tr><th>station</th><th class='num'>runs</th>";
  for (const char* h : {"mean", "std", "min", "Q1", "median", "Q3", "max"})
    s += std::string("<th class='num'>") + h + " (" + esc(info.human_unit) + ")</th>";
  if (by_frame) s += "<th class='num'>left out: another body frame</th>";
  s += "</tr>\n";
  for (const auto& d : dist) s += distribution_row(q, d, info);
  return s + "</table>\n";
}

}  // namespace

std::string fleet_page(const History& history, const Params& query) {
  const FleetQuery q = parse_query(history, query);
  const auto counts = history.stats->runs_per_station_day(q.filter);
  const auto verdicts = history.stats->verdict_counts_per_station(q.filter);
  const std::vector<db::history::ParamSummary> dist =
      q.param ? history.stats->param_distribution(*q.param, q.filter)
              : std::vector<db::history::ParamSummary>{};
  std::vector<std::string> stations;
  for (const auto& v : verdicts) stations.push_back(v.station);
  std::string b = "<h1>Fleet: runs, verdicts and parameters per station</h1>\n";
  b += "<p class='muted'>" + esc(history.label) + ", read-only.</p>\n";
  b += signatures_banner(history);
  b += filter_form(q) + window_line(q);
  b += runs_chart_section(q, counts, stations);
  b += verdict_section(q, verdicts);
  std::string target = "/fleet";  // the page's own filters, as given
  for (const auto& [name, value] : q.echo)
    if (!value.empty()) target += (target.size() == 6 ? "?" : "&") + name + "=" + url_encode(value);
  b += download_links(target);
  b += distribution_section(q, dist);
  b += runs_table_section(q, counts, stations);
  return page("Fleet", b);
}

namespace {

/// The page's figures as data (issue #52: what a page shows, downloadable): JSON with every table
/// (runs per station and day, verdicts per station, the distribution in SI units), CSV a row per
/// station with its verdict counts, yield and, with a parameter, its distribution.
Reply fleet_data(const FleetQuery& q, const std::vector<db::history::StationDayCount>& counts,
                 const std::vector<db::history::StationVerdictCounts>& verdicts,
                 const std::vector<db::history::ParamSummary>& dist, Format format) {
  const auto yield = [](const db::history::StationVerdictCounts& v) {
    return v.unit_outcomes() ? static_cast<double>(v.pass) / v.unit_outcomes() : 0.0;
  };
  std::map<std::string, const db::history::ParamSummary*> by_station;
  for (const auto& d : dist) by_station[d.station] = &d;
  if (format == Format::kJson) {
    nlohmann::json j;
    j["since_ms"] = q.filter.since_ms ? nlohmann::json(*q.filter.since_ms) : nlohmann::json();
    j["until_ms"] = q.filter.until_ms ? nlohmann::json(*q.filter.until_ms) : nlohmann::json();
    j["setting"] = q.filter.setting ? nlohmann::json(*q.filter.setting) : nlohmann::json("all");
    j["verdict"] = q.filter.verdict ? nlohmann::json(*q.filter.verdict) : nlohmann::json();
    j["runs_per_day"] = nlohmann::json::array();
    for (const auto& c : counts)
      j["runs_per_day"].push_back(
          {{"station", c.station}, {"day", utc_date(c.day * kDayMs)}, {"runs", c.runs}});
    j["verdicts"] = nlohmann::json::array();
    for (const auto& v : verdicts)
      j["verdicts"].push_back(
          {{"station", v.station},
           {"PASS", v.pass},
           {"REVIEW", v.review},
           {"FAILED", v.failed},
           {"STATION-FAULT", v.station_fault},
           {"ABORTED", v.aborted},
           {"INTERRUPTED", v.interrupted},
           {"live", v.live},
           {"yield", v.unit_outcomes() ? nlohmann::json(yield(v)) : nlohmann::json()}});
    if (q.param) {
      j["param"] = calib::core::param_info(*q.param).name;
      j["distribution_si"] = nlohmann::json::array();
      for (const auto& d : dist)
        j["distribution_si"].push_back({{"station", d.station},
                                        {"count", d.count},
                                        {"mean", d.mean},
                                        {"std", d.std_dev},
                                        {"min", d.min},
                                        {"q1", d.q1},
                                        {"median", d.median},
                                        {"q3", d.q3},
                                        {"max", d.max},
                                        {"other_frame", d.other_frame}});
    }
    return {j.dump(2) + "\n", "application/json", "fleet.json"};
  }
  std::string out = "station,PASS,REVIEW,FAILED,STATION-FAULT,ABORTED,INTERRUPTED,live,yield";
  if (q.param) out += ",param,count,mean_si,std_si,min_si,q1_si,median_si,q3_si,max_si,other_frame";
  out += "\n";
  for (const auto& v : verdicts) {
    out += csv_field(v.station) + "," + std::to_string(v.pass) + "," + std::to_string(v.review) +
           "," + std::to_string(v.failed) + "," + std::to_string(v.station_fault) + "," +
           std::to_string(v.aborted) + "," + std::to_string(v.interrupted) + "," +
           std::to_string(v.live) + "," + (v.unit_outcomes() ? exact(yield(v)) : "");
    if (q.param) {
      out += "," + calib::core::param_info(*q.param).name;
      const auto it = by_station.find(v.station);
      if (it == by_station.end()) {
        out += ",0,,,,,,,,0";
      } else {
        const auto& d = *it->second;
        out += "," + std::to_string(d.count);
        for (const double x : {d.mean, d.std_dev, d.min, d.q1, d.median, d.q3, d.max})
          out += "," + (d.count ? exact(x) : std::string());
        out += "," + std::to_string(d.other_frame);
      }
    }
    out += "\n";
  }
  return {out, "text/csv; charset=utf-8", "fleet.csv"};
}

}  // namespace

Reply fleet_reply(const History& history, const Params& query) {
  check_known_params(
      query, {"since", "until", "station", "serial", "param", "setting", "verdict", "format"});
  const Format format = parse_format(query);
  if (format == Format::kHtml) return Reply(fleet_page(history, query));
  const FleetQuery q = parse_query(history, query);
  const std::vector<db::history::ParamSummary> dist =
      q.param ? history.stats->param_distribution(*q.param, q.filter)
              : std::vector<db::history::ParamSummary>{};
  return fleet_data(q, history.stats->runs_per_station_day(q.filter),
                    history.stats->verdict_counts_per_station(q.filter), dist, format);
}

}  // namespace imucal::tools::stationweb
