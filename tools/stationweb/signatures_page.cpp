// "/signatures": station signatures (issue #25) of one period — each station's departure from the
// fleet fitted by every station error (size ± σ, z), and the flagged stations with their likely
// cause, the advice and the runs they touch (station/station_signatures.hpp computes it, as for
// `stationctl stations --signatures`).
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
         " " + esc(fit["unit"].get<std::string>()) + " <span class='muted'>(z " + fmt("%+.1f", z) +
         ")</span></td>";
}

std::string station_row(const nlohmann::json& st) {
  const bool flagged = st.value("flagged", false);
  std::string s = "<tr data-station='" + esc(st["station"].get<std::string>()) +
                  "' data-flagged='" + (flagged ? "1" : "0") + "'><td>" +
                  esc(st["station"].get<std::string>()) + "</td><td class='num'>" +
                  std::to_string(st["runs"].get<int>()) + "</td><td class='num'>" +
                  std::to_string(st["population_units"].get<int>()) + "</td><td class='num'>" +
                  std::to_string(st["repeat_units"].get<int>()) + "</td>";
  if (!st["assessed"].get<bool>())
    return s + "<td colspan='3'>not assessed: " + esc(st["why_not"].get<std::string>()) +
           "</td></tr>\n";
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
  return s + "</p></div>\n";
}

}  // namespace

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
  for (const auto& fit : report["stations"][0]["fits"])
    b += "<th class='num'>" + esc(fit["effect"].get<std::string>()) + "</th>";
  b += "<th></th></tr>\n";
  for (const auto& st : report["stations"]) b += station_row(st);
  return page("Station signatures", b + "</table>\n");
}

}  // namespace imucal::stationweb
