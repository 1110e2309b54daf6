// "/signatures": station signatures (issue #25) of one period — each station's departure from the
// fleet fitted by every station error (size ± σ, z), and the flagged stations with their likely
// cause, the advice and the runs they touch (station/station_signatures.hpp computes it, as for
// `stationctl stations --signatures`).
#include <map>
#include <mutex>

#include "station/station_signatures.hpp"
#include "tools/stationweb/html.hpp"
#include "tools/stationweb/pages.hpp"

namespace imucal::stationweb {

namespace {

db::FleetFilter window_of(const History& history, const Params& query) {
  try {
    return station::signature_window(*history.repo, query_value(query, "since"),
                                     query_value(query, "until"));
  } catch (const station::WindowError& e) {
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
                  esc(st["station"].get<std::string>()) + "</h3><p>" +
                  esc(st["alarm"]["cause"].get<std::string>()) + ".</p><p>Runs it touches (" +
                  std::to_string(st["run_ids"].size()) + "):";
  for (const auto& id : st["run_ids"]) s += " " + run_link(id.get<db::RunId>());
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
nlohmann::json cached_default_report(const History& history, const db::FleetFilter& window) {
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
  nlohmann::json report =
      station::station_signature_report(*history.stats, window, calib::SignatureOptions{});
  const std::lock_guard<std::mutex> lock(mutex);
  if (cache.size() > 16) cache.clear();  // old windows and old newest runs
  return cache[key] = std::move(report);
}

}  // namespace

std::string signatures_banner(const History& history) {
  db::FleetFilter window;
  nlohmann::json report;
  try {
    window = station::signature_window(*history.repo, "", "");
    if (!window.until_ms) return "";
    report = cached_default_report(history, window);
  } catch (const db::InvalidInput& e) {
    // A history whose main sequence the library does not hold: the page stands without it.
    return "<p id='signature-banner' class='muted'>Station signatures unavailable: " +
           esc(e.what()) + "</p>\n";
  }
  std::string flagged;
  int n = 0;
  for (const auto& st : report["stations"])
    if (st.value("flagged", false)) {
      flagged += "<li data-station='" + esc(st["station"].get<std::string>()) + "'><b>" +
                 esc(st["station"].get<std::string>()) +
                 "</b>: " + esc(st["alarm"]["cause"].get<std::string>()) + " (" +
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
  const db::FleetFilter window = window_of(history, query);
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
  const nlohmann::json report =
      station::station_signature_report(*history.stats, window, calib::SignatureOptions{});
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

}  // namespace imucal::stationweb
