// "/signatures": station signatures (issue #25) of one period — each station's departure from the
// fleet fitted by every station error (size ± σ, z), and the flagged stations with their likely
// cause, the advice and the runs they touch (tools/report/station_signatures.hpp computes it, as
// for `stationctl stations --signatures`).
#include <map>
#include <mutex>

#include "tools/report/station_signatures.hpp"
#include "tools/stationweb/fleet_svg.hpp"
#include "tools/stationweb/html.hpp"
#include "tools/stationweb/page_limits.hpp"
#include "tools/stationweb/page_util.hpp"
#include "tools/stationweb/pages.hpp"
#include "tools/stationweb/run_table.hpp"

namespace imucal::tools::stationweb {

namespace {

/// The signature window of since/until (dates outside the served range clamped, `notes` saying
/// so: page_limits.hpp).
db::history::FleetFilter window_of(const History& history, const Params& query, std::string& notes,
                                   int default_days = 7) {
  const std::string since = clamped_date_text("since", query_value(query, "since"), false, notes);
  const std::string until = clamped_date_text("until", query_value(query, "until"), true, notes);
  try {
    return tools::report::signature_window(*history.repo, since, until, default_days);
  } catch (const tools::report::WindowError& e) {
    bad_input(e.field, e.reason);
  }
}

std::string note_span(const std::string& notes) {
  return notes.empty() ? "" : " <span id='window-note' class='REVIEW'>" + esc(notes) + "</span>";
}

/// 400 naming since when the window holds more factory runs than a signature page reads
/// (kMaxSignatureRuns): their AINS results are held in memory together.
void check_signature_runs(const History& history, const db::history::FleetFilter& window) {
  db::history::FleetFilter factory = window;
  factory.setting = "factory";
  std::int64_t runs = 0;
  for (const auto& v : history.stats->verdict_counts_per_station(factory))
    runs += v.unit_outcomes() + v.live;
  if (runs > kMaxSignatureRuns)
    bad_input("since", "the window holds " + std::to_string(runs) +
                           " factory runs; the signatures read at most " +
                           std::to_string(kMaxSignatureRuns) + " at once: narrow since/until");
}

/// The runs of other sequences than the one the responses are measured on (issue #52): left out,
/// counted, not fitted with another sequence's responses.
std::string left_out_note(const nlohmann::json& report) {
  if (!report.contains("other_sequences") || report["other_sequences"].empty()) return "";
  std::string list;
  for (const auto& o : report["other_sequences"])
    list += (list.empty() ? "" : ", ") + count_of(o["runs"].get<std::int64_t>(), "run") + " of " +
            esc(o["sequence"].get<std::string>());
  return "<p id='other-sequences' class='REVIEW'>Left out: " + list +
         " — a station error moves a run's parameters by its own sequence's responses, and these "
         "are measured on " +
         esc(report["sequence"].get<std::string>()) + " only.</p>\n";
}

std::string fit_cell(const nlohmann::json& fit) {
  const double z = fit["z"].get<double>();
  return "<td class='num' data-effect='" + esc(fit["effect"].get<std::string>()) + "' data-z='" +
         exact(z) + "' data-size-si='" + exact(fit["size_si"].get<double>()) + "'>" +
         fmt("%+.3g", fit["size"].get<double>()) + " ± " + fmt("%.2g", fit["sigma"].get<double>()) +
         " " + esc(fit["unit"].get<std::string>()) + "<br><span class='muted'>z " +
         fmt("%+.1f", z) + "</span></td>";
}

std::string station_row(const nlohmann::json& st, std::size_t candidates) {
  const bool flagged = st.value("flagged", false);
  std::string s = "<tr data-station='" + esc(st["station"].get<std::string>()) +
                  "' data-flagged='" + (flagged ? "1" : "0") + "' data-runs='" +
                  std::to_string(st["runs"].get<int>()) + "'><td>" +
                  esc(st["station"].get<std::string>()) + "</td><td class='num'>" +
                  std::to_string(st["runs"].get<int>()) + "</td><td class='num' data-units='" +
                  std::to_string(st["units"].get<int>()) + "' data-population-units='" +
                  std::to_string(st["population_units"].get<int>()) + "'>" +
                  std::to_string(st["units"].get<int>()) + "</td><td class='num'>" +
                  std::to_string(st["repeat_units"].get<int>()) + "</td>";
  if (!st["assessed"].get<bool>())
    return s + "<td colspan='" + std::to_string(candidates + 1) +
           "'>not assessed: " + esc(st["why_not"].get<std::string>()) + "</td></tr>\n";
  for (const auto& fit : st["fits"]) s += fit_cell(fit);
  return s + "<td>" + (flagged ? "<span class='FAILED'>FLAGGED</span>" : "ok") + "</td></tr>\n";
}

std::string alarm_section(const nlohmann::json& st) {
  std::string s = "<div class='alarm' data-station='" + esc(st["station"].get<std::string>()) +
                  "' data-effect='" + esc(st["alarm"]["effect"].get<std::string>()) + "'><h3>" +
                  esc(st["station"].get<std::string>()) + "</h3>";
  for (const auto& alarm : st["alarms"])
    s += "<p data-cause='" + esc(alarm["effect"].get<std::string>()) + "'>" +
         esc(alarm["cause"].get<std::string>()) + ".</p>";
  s += "<p>Runs it touches (" + std::to_string(st["run_ids"].size()) + "):";
  for (const auto& id : st["run_ids"]) s += " " + run_link(id.get<db::history::RunId>());
  s += "</p>";
  const auto& remedy = st["remedy"];
  if (remedy.value("reprocess", false))
    s += "<p class='remedy'>Once the site's gravity is re-surveyed, at " +
         esc(st["station"].get<std::string>()) +
         " (G the new survey, m/s²):</p><pre class='command'>" +
         esc(remedy["command"].get<std::string>()) +
         "</pre><p class='muted'>The new runs stand beside the old ones; QA promotes them.</p>";
  else
    s += "<p class='remedy'>" + esc(remedy["text"].get<std::string>()) + ".</p>";
  return s + "</div>\n";
}

/// The default window's report, computed once per (history, window, newest run): the fleet page
/// shows its flags on every load, and a week's AINS results need not be read again until a run
/// arrives. Pages are served from several threads.
nlohmann::json cached_default_report(const History& history,
                                     const db::history::FleetFilter& window) {
  static std::mutex mutex;
  static std::map<std::string, nlohmann::json> cache;
  const auto newest = history.repo->recent_runs(1);
  const std::string key = history.label + "|" + std::to_string(*window.since_ms) + "|" +
                          std::to_string(*window.until_ms) + "|" +
                          (newest.empty() ? "" : std::to_string(newest.front().run_id));
  {
    const std::lock_guard<std::mutex> lock(mutex);
    if (const auto it = cache.find(key); it != cache.end()) return it->second;
  }
  nlohmann::json report = tools::report::station_signature_report(
      *history.stats, window, calib::studies::fleet::SignatureOptions{});
  const std::lock_guard<std::mutex> lock(mutex);
  if (cache.size() > 16) cache.clear();  // old windows and old newest runs
  return cache[key] = std::move(report);
}

}  // namespace

std::string signatures_banner(const History& history) {
  db::history::FleetFilter window;
  nlohmann::json report;
  try {
    window = tools::report::signature_window(*history.repo, "", "");
    if (!window.until_ms) return "";
    report = cached_default_report(history, window);
  } catch (const db::history::InvalidInput& e) {
    // A history whose main sequence the library does not hold: the page stands without it.
    return "<p id='signature-banner' class='muted'>Station signatures unavailable: " +
           esc(e.what()) + "</p>\n";
  }
  std::string flagged, not_assessed;
  int n = 0, assessed = 0, unassessed = 0;
  for (const auto& st : report["stations"]) {
    const std::string name = st["station"].get<std::string>();
    if (!st["assessed"].get<bool>()) {
      // Issue #52 item 3: what /signatures says of it, not silence read as "not flagged".
      not_assessed += "<li data-station='" + esc(name) + "' data-assessed='0'><b>" + esc(name) +
                      "</b>: not assessed: " + esc(st["why_not"].get<std::string>()) + "</li>";
      ++unassessed;
      continue;
    }
    ++assessed;
    if (!st.value("flagged", false)) continue;
    std::string causes;
    for (const auto& alarm : st["alarms"])
      causes += (causes.empty() ? "" : "; ") + alarm["cause"].get<std::string>();
    flagged += "<li data-station='" + esc(name) + "'><b>" + esc(name) + "</b>: " + esc(causes) +
               " (" + count_of(static_cast<std::int64_t>(st["run_ids"].size()), "run") + ")</li>";
    ++n;
  }
  const std::string week = "the week to " + short_time(*window.until_ms) + " UTC";
  const std::string attrs = " data-flagged='" + std::to_string(n) + "' data-assessed='" +
                            std::to_string(assessed) + "' data-not-assessed='" +
                            std::to_string(unassessed) + "'";
  const std::string link = " (<a href='/signatures'>signatures</a>)";
  std::string text;
  if (report["stations"].empty())
    text = "no factory AINS results to assess";
  else if (n == 0 && unassessed == 0)
    text = "no station flagged";
  else if (n == 0)
    text = assessed == 0 ? "no station assessed"
                         : "no station flagged among the " + count_of(assessed, "assessed station");
  if (!text.empty() && not_assessed.empty())
    return "<p id='signature-banner' class='muted'" + attrs + ">Station signatures over " + week +
           ": " + text + link + ".</p>\n";
  std::string head = n == 0
                         ? "Station signatures over " + week + ": " + text + link + ":"
                         : std::to_string(n) + (n == 1 ? " station departs" : " stations depart") +
                               " from the fleet over " + week + link + ":";
  return "<div id='signature-banner' class='" + std::string(n ? "alarm" : "muted") + "'" + attrs +
         "><p>" + head + "</p><ul>" + flagged + not_assessed + "</ul></div>\n";
}

std::string signatures_page(const History& history, const Params& query) {
  std::string notes;
  const db::history::FleetFilter window = window_of(history, query, notes);
  std::string b = "<h1>Station signatures: what one run cannot see</h1>\n";
  b += "<form class='filters' action='/signatures' method='get'><label>since <input name='since' "
       "size='12' value='" +
       esc(query_value(query, "since")) +
       "'></label><label>until <input "
       "name='until' size='12' value='" +
       esc(query_value(query, "until")) + "'></label> <button type='submit'>Show</button></form>\n";
  if (!window.until_ms) return page("Station signatures", b + "<p>No runs stored yet.</p>\n");
  b += "<p id='window' data-since-ms='" + std::to_string(*window.since_ms) + "' data-until-ms='" +
       std::to_string(*window.until_ms) + "'>Factory AINS results of runs started from " +
       short_time(*window.since_ms) + " until (before) " + short_time(*window.until_ms) + " UTC." +
       note_span(notes) + "</p>\n";
  check_signature_runs(history, window);
  const nlohmann::json report = tools::report::station_signature_report(
      *history.stats, window, calib::studies::fleet::SignatureOptions{});
  if (report["stations"].empty())
    return page("Station signatures", b + "<p>No factory AINS results in this window.</p>\n");
  b += "<p>Each station's units against the other stations' (against the units' own spread), and "
       "units seen at several stations — re-calibrated or golden units — against themselves "
       "(against their runs' σ); each station error fitted to the difference. Flagged at |z| ≥ " +
       fmt("%.2f", report["z_threshold"].get<double>()) + " (false alarms " +
       fmt("%.3g", report["false_alarm"].get<double>()) +
       " per station and period); responses on " + esc(report["sequence"].get<std::string>()) +
       ".</p>\n" + left_out_note(report);
  std::string alarms;
  for (const auto& st : report["stations"])
    if (st.value("flagged", false)) alarms += alarm_section(st);
  b += "<h2>Flagged stations</h2>\n" + (alarms.empty() ? "<p>None.</p>\n" : alarms);
  b += "<p><a href='/signatures/trend'>Period by period</a>: the last 12 weeks' signatures.</p>\n";
  std::string target = "/signatures";
  for (const char* name : {"since", "until"})
    if (const std::string v = query_value(query, name); !v.empty())
      target += (target.size() == 11 ? "?" : "&") + std::string(name) + "=" + url_encode(v);
  b += download_links(target);
  b += "<h2>Every station</h2>\n<table id='signatures'>\n<tr><th>station</th><th "
       "class='num'>runs</th><th class='num'>units</th><th class='num'>seen elsewhere</th>";
  // Every assessed station has a fit per candidate; one not assessed has none.
  nlohmann::json header_fits = nlohmann::json::array();
  for (const auto& st : report["stations"])
    if (st["fits"].size() > header_fits.size()) header_fits = st["fits"];
  for (const auto& fit : header_fits) {
    std::string name = fit["effect"].get<std::string>();  // "table_wobble_x": may wrap
    for (char& c : name)
      if (c == '_') c = ' ';
    b += "<th class='num'>" + esc(name) + "</th>";
  }
  const std::size_t candidates = header_fits.size();
  b += "<th></th></tr>\n";
  for (const auto& st : report["stations"]) b += station_row(st, candidates);
  return page("Station signatures", b + "</table>\n");
}

namespace {

int period_days_of(const Params& query) {
  const std::string text = query_value(query, "period_days");
  if (text.empty()) return 7;
  std::size_t used = 0;
  int days = 0;
  try {
    days = std::stoi(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used != text.size() || days < 1 || days > 366)
    bad_input("period_days", "'" + text + "' is not a whole number of days from 1 to 366");
  return days;
}

/// The trend's window (issue #52 items 5 and 12): since/until clamped to the served dates; the end
/// no later than the newest run's day (no period after it holds a run); periods starting at
/// `since` when it is given (the end moved on to close the last one), at most kMaxTrendPeriods
/// of them — the newest. `notes` says what was moved and why.
db::history::FleetFilter trend_window(const History& history, const Params& query, int period_days,
                                      std::string& notes) {
  db::history::FleetFilter w = window_of(history, query, notes, 12 * period_days);
  if (!w.until_ms) return w;
  const db::history::TimestampMs period_ms = period_days * kDayMs;
  const auto newest = history.repo->recent_runs(1);
  if (newest.empty()) return w;  // an empty history with until given: nothing to cut
  const db::history::TimestampMs newest_end =
      (db::history::utc_day(newest.front().started_at_ms) + 1) * kDayMs;
  if (*w.until_ms > newest_end) {
    w.until_ms = newest_end;
    if (*w.since_ms >= newest_end) w.since_ms = newest_end - period_ms;
    notes += "The window ends with the newest run's day, " + utc_date(newest_end - 1) + ". ";
  }
  const db::history::TimestampMs span = *w.until_ms - *w.since_ms;
  const db::history::TimestampMs n = (span + period_ms - 1) / period_ms;
  if (n > kMaxTrendPeriods) {
    w.since_ms = *w.until_ms - kMaxTrendPeriods * period_ms;
    notes += "At most " + std::to_string(kMaxTrendPeriods) + " periods are shown: the newest " +
             std::to_string(kMaxTrendPeriods) + ", from " + utc_date(*w.since_ms) + ". ";
  } else if (!query_value(query, "since").empty() && span % period_ms != 0) {
    w.until_ms = *w.since_ms + n * period_ms;
    notes += "Periods start at since; the last one ends " + short_time(*w.until_ms) + " UTC. ";
  }
  return w;
}

/// Station × period: the strongest |z| ('*' and the cause's effect when flagged).
std::string trend_table(const nlohmann::json& trend) {
  std::string b = "<table id='trend'>\n<tr><th>station</th>";
  for (const auto& p : trend["periods"])
    b += "<th class='num'>" + utc_date(p["since_ms"].get<db::history::TimestampMs>()) + "</th>";
  b += "</tr>\n";
  for (const auto& name : trend["stations"]) {
    b += "<tr><td>" + esc(name.get<std::string>()) + "</td>";
    for (const auto& p : trend["periods"]) {
      const std::string period = utc_date(p["since_ms"].get<db::history::TimestampMs>());
      const nlohmann::json* cell = tools::report::signature_trend_cell(p, name.get<std::string>());
      if (!cell || !cell->contains("strongest")) {
        b += "<td class='num muted'>–</td>";
        continue;
      }
      const bool flagged = (*cell)["flagged"].get<bool>();
      b += "<td class='num' data-station='" + esc(name.get<std::string>()) + "' data-period='" +
           period + "' data-flagged='" + (flagged ? "1" : "0") + "'" +
           (flagged ? " title='" + esc((*cell)["cause"].get<std::string>()) + "'" : "") + ">" +
           fmt("%.1f", std::abs((*cell)["strongest"]["z"].get<double>())) +
           (flagged ? " <span class='FAILED'>" +
                          esc((*cell)["alarm"]["effect"].get<std::string>()) + "</span>"
                    : "") +
           "</td>";
    }
    b += "</tr>\n";
  }
  return b + "</table>\n";
}

}  // namespace

std::string signature_trend_page(const History& history, const Params& query) {
  const int period_days = period_days_of(query);
  std::string notes;
  const db::history::FleetFilter window = trend_window(history, query, period_days, notes);
  std::string b = "<h1>Station signatures period by period</h1>\n";
  b += "<form class='filters' action='/signatures/trend' method='get'><label>since <input "
       "name='since' size='12' value='" +
       esc(query_value(query, "since")) +
       "'></label><label>until <input name='until' size='12' "
       "value='" +
       esc(query_value(query, "until")) +
       "'></label><label>period (days) <input name='period_days' size='4' value='" +
       std::to_string(period_days) + "'></label> <button type='submit'>Show</button></form>\n";
  if (!window.until_ms) return page("Signature trend", b + "<p>No runs stored yet.</p>\n");
  b += "<p id='window' data-since-ms='" + std::to_string(*window.since_ms) + "' data-until-ms='" +
       std::to_string(*window.until_ms) + "' data-periods='" +
       std::to_string((*window.until_ms - *window.since_ms) / (period_days * kDayMs)) +
       "'>Periods of " + count_of(period_days, "day") + " from " + short_time(*window.since_ms) +
       " until (before) " + short_time(*window.until_ms) + " UTC." + note_span(notes) + "</p>\n";
  check_signature_runs(history, window);
  const nlohmann::json trend = tools::report::station_signature_trend(
      *history.stats, window, period_days, calib::studies::fleet::SignatureOptions{});
  if (trend["stations"].empty())
    return page("Signature trend", b + "<p>No factory AINS results in this window.</p>\n");
  b += "<p>Each period's signatures on their own (<a href='/signatures'>one period</a>): a "
       "station error that grows between services — a table drifting out of square, a fixture "
       "working loose — rises period by period; a flagged point is ringed red, its cause in the "
       "table's tooltip.</p>\n";
  b += signature_trend_svg(trend);
  b += "<h2>Strongest |z| per station and period</h2>\n" + trend_table(trend);
  return page("Signature trend", b);
}

namespace {

/// A signature report's stations as CSV: a row each, then each candidate's size, σ (SI) and z.
std::string stations_csv(const nlohmann::json& stations, const std::string& lead_header,
                         const std::string& lead) {
  nlohmann::json effects = nlohmann::json::array();
  for (const auto& st : stations)
    if (st.contains("fits") && st["fits"].size() > effects.size()) effects = st["fits"];
  std::string out =
      lead_header + "station,runs,units,seen_elsewhere,assessed,why_not,flagged,causes";
  for (const auto& f : effects) {
    const std::string e = f["effect"].get<std::string>();
    out += "," + e + "_size_si," + e + "_sigma_si," + e + "_z";
  }
  out += "\n";
  for (const auto& st : stations) {
    std::string causes;
    if (st.contains("alarms"))
      for (const auto& a : st["alarms"])
        causes += (causes.empty() ? "" : "; ") + a["cause"].get<std::string>();
    out += lead + csv_field(st["station"].get<std::string>()) + "," +
           std::to_string(st.value("runs", 0)) + "," + std::to_string(st.value("units", 0)) + "," +
           std::to_string(st.value("repeat_units", 0)) + "," +
           (st.value("assessed", false) ? "1" : "0") + "," + csv_field(st.value("why_not", "")) +
           "," + (st.value("flagged", false) ? "1" : "0") + "," + csv_field(causes);
    for (std::size_t k = 0; k < effects.size(); ++k) {
      if (!st.contains("fits") || k >= st["fits"].size()) {
        out += ",,,";
        continue;
      }
      const auto& f = st["fits"][k];
      out += "," + exact(f["size_si"].get<double>()) + "," + exact(f["sigma_si"].get<double>()) +
             "," + exact(f["z"].get<double>());
    }
    out += "\n";
  }
  return out;
}

}  // namespace

Reply signatures_reply(const History& history, const Params& query) {
  check_known_params(query, {"since", "until", "format"});
  const Format format = parse_format(query);
  if (format == Format::kHtml) return Reply(signatures_page(history, query));
  std::string notes;
  const db::history::FleetFilter window = window_of(history, query, notes);
  nlohmann::json report = {{"runs", 0}, {"stations", nlohmann::json::array()}};
  if (window.until_ms) {
    check_signature_runs(history, window);
    report = tools::report::station_signature_report(*history.stats, window,
                                                     calib::studies::fleet::SignatureOptions{});
    report["since_ms"] = *window.since_ms;
    report["until_ms"] = *window.until_ms;
  }
  if (!notes.empty()) report["notes"] = notes;
  if (format == Format::kJson)
    return {report.dump(2) + "\n", "application/json", "signatures.json"};
  return {stations_csv(report["stations"], "", ""), "text/csv; charset=utf-8", "signatures.csv"};
}

Reply signature_trend_reply(const History& history, const Params& query) {
  check_known_params(query, {"since", "until", "period_days", "format"});
  const Format format = parse_format(query);
  if (format == Format::kHtml) return Reply(signature_trend_page(history, query));
  const int period_days = period_days_of(query);
  std::string notes;
  const db::history::FleetFilter window = trend_window(history, query, period_days, notes);
  nlohmann::json trend = {{"period_days", period_days}, {"periods", nlohmann::json::array()}};
  if (window.until_ms) {
    check_signature_runs(history, window);
    trend = tools::report::station_signature_trend(*history.stats, window, period_days,
                                                   calib::studies::fleet::SignatureOptions{});
  }
  if (!notes.empty()) trend["notes"] = notes;
  if (format == Format::kJson)
    return {trend.dump(2) + "\n", "application/json", "signature-trend.json"};
  std::string out =
      "period_since,period_until,station,assessed,flagged,strongest_effect,"
      "strongest_z,cause\n";
  for (const auto& p : trend["periods"])
    for (const auto& cell : p["stations"]) {
      const bool has = cell.contains("strongest");
      out += db::history::format_time_utc(p["since_ms"].get<db::history::TimestampMs>()) + "," +
             db::history::format_time_utc(p["until_ms"].get<db::history::TimestampMs>()) + "," +
             csv_field(cell["station"].get<std::string>()) + "," +
             (cell.value("assessed", false) ? "1" : "0") + "," +
             (cell.value("flagged", false) ? "1" : "0") + "," +
             (has ? csv_field(cell["strongest"]["effect"].get<std::string>()) : "") + "," +
             (has ? exact(cell["strongest"]["z"].get<double>()) : "") + "," +
             csv_field(cell.value("cause", "")) + "\n";
    }
  return {out, "text/csv; charset=utf-8", "signature-trend.csv"};
}

}  // namespace imucal::tools::stationweb
