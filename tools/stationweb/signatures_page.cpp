// "/signatures": station signatures (issue #25) of one period — each station's departure from the
// fleet fitted by every station error (size ± σ, z), and the flagged stations with their likely
// cause, the advice and the runs they touch (tools/report/station_signatures.hpp computes it, as
// for `stationctl stations --signatures`).
#include <map>
#include <mutex>

#include "tools/report/station_signatures.hpp"
#include "tools/stationweb/fleet_svg.hpp"
#include "tools/stationweb/html.hpp"
#include "tools/stationweb/pages.hpp"

namespace imucal::tools::stationweb {

namespace {

db::history::FleetFilter window_of(const History& history, const Params& query,
                                   int default_days = 7) {
  try {
    return tools::report::signature_window(*history.repo, query_value(query, "since"),
                                           query_value(query, "until"), default_days);
  } catch (const tools::report::WindowError& e) {
    bad_input(e.field, e.reason);
  }
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
                  "' data-flagged='" + (flagged ? "1" : "0") + "'><td>" +
                  esc(st["station"].get<std::string>()) + "</td><td class='num'>" +
                  std::to_string(st["runs"].get<int>()) + "</td><td class='num'>" +
                  std::to_string(st["population_units"].get<int>()) + "</td><td class='num'>" +
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
  std::string flagged;
  int n = 0;
  for (const auto& st : report["stations"])
    if (st.value("flagged", false)) {
      std::string causes;
      for (const auto& alarm : st["alarms"])
        causes += (causes.empty() ? "" : "; ") + alarm["cause"].get<std::string>();
      flagged += "<li data-station='" + esc(st["station"].get<std::string>()) + "'><b>" +
                 esc(st["station"].get<std::string>()) + "</b>: " + esc(causes) + " (" +
                 std::to_string(st["run_ids"].size()) + " runs)</li>";
      ++n;
    }
  const std::string week = "the week to " + short_time(*window.until_ms) + " UTC";
  if (n == 0)
    return "<p id='signature-banner' class='muted' data-flagged='0'>Station signatures over " +
           week + ": no station flagged (<a href='/signatures'>signatures</a>).</p>\n";
  return "<div id='signature-banner' class='alarm' data-flagged='" + std::to_string(n) + "'><p>" +
         std::to_string(n) + (n == 1 ? " station departs" : " stations depart") +
         " from the fleet over " + week + " (<a href='/signatures'>signatures</a>):</p><ul>" +
         flagged + "</ul></div>\n";
}

std::string signatures_page(const History& history, const Params& query) {
  const db::history::FleetFilter window = window_of(history, query);
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
       short_time(*window.since_ms) + " until (before) " + short_time(*window.until_ms) +
       " UTC.</p>\n";
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
       ".</p>\n";
  std::string alarms;
  for (const auto& st : report["stations"])
    if (st.value("flagged", false)) alarms += alarm_section(st);
  b += "<h2>Flagged stations</h2>\n" + (alarms.empty() ? "<p>None.</p>\n" : alarms);
  b += "<p><a href='/signatures/trend'>Period by period</a>: the last 12 weeks' signatures.</p>\n";
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

/// Station × period: the strongest |z| ('*' and the cause's effect when flagged).
std::string trend_table(const nlohmann::json& trend) {
  std::string b = "<table id='trend'>\n<tr><th>station</th>";
  for (const auto& p : trend["periods"])
    b += "<th class='num'>" +
         db::history::format_time_utc(p["since_ms"].get<db::history::TimestampMs>()).substr(5, 5) +
         "</th>";
  b += "</tr>\n";
  for (const auto& name : trend["stations"]) {
    b += "<tr><td>" + esc(name.get<std::string>()) + "</td>";
    for (const auto& p : trend["periods"]) {
      const std::string period =
          db::history::format_time_utc(p["since_ms"].get<db::history::TimestampMs>()).substr(0, 10);
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
  const db::history::FleetFilter window = window_of(history, query, 12 * period_days);
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

}  // namespace imucal::tools::stationweb
