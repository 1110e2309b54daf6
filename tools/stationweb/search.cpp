// Issue #52 items 8 and 10: what a page does with a query it cannot use — a parameter it does not
// take, a serial the history does not hold (with the units that differ only in case), blanks around
// a pasted serial — and the form an error page keeps so the request can be corrected in place.
#include <algorithm>
#include <cctype>

#include "db/history/fleet_stats.hpp"
#include "db/history/serial_number.hpp"
#include "tools/stationweb/html.hpp"
#include "tools/stationweb/pages.hpp"

namespace imucal::tools::stationweb {

namespace {

/// The serials a NotFound names after "did you mean " (db::history::did_you_mean: joined by
/// " or ", ended by "?"): the backend found them, the page only links them.
std::vector<std::string> suggestions_in(const std::string& message) {
  std::vector<std::string> out;
  const std::string key = "did you mean ";
  const std::size_t at = message.find(key);
  if (at == std::string::npos) return out;
  const std::size_t end = message.find('?', at);
  std::string list = message.substr(
      at + key.size(), end == std::string::npos ? std::string::npos : end - at - key.size());
  for (std::size_t p = 0; p <= list.size();) {
    const std::size_t q = std::min(list.find(" or ", p), list.size());
    if (q > p) out.push_back(list.substr(p, q - p));
    p = q + 4;
  }
  return out;
}

/// The parameters each page with a query takes, in its form's order.
const std::vector<std::pair<std::string, std::vector<std::string>>>& page_params() {
  static const std::vector<std::pair<std::string, std::vector<std::string>>> table = {
      {"/", {"limit"}},
      {"/unit", {"serial"}},
      {"/runs", {"station", "serial", "verdict", "setting", "since", "until", "param", "limit"}},
      {"/compare", {"a", "b", "method"}},
      {"/fleet", {"since", "until", "station", "serial", "param"}},
      {"/signatures", {"since", "until"}},
      {"/signatures/trend", {"since", "until", "period_days"}}};
  return table;
}

}  // namespace

std::string trimmed(const std::string& text) {
  const auto blank = [](char c) { return std::isspace(static_cast<unsigned char>(c)) != 0; };
  const auto b = std::find_if_not(text.begin(), text.end(), blank);
  const auto e = std::find_if_not(text.rbegin(), text.rend(), blank).base();
  return b < e ? std::string(b, e) : std::string();
}

Format parse_format(const Params& query) {
  const std::string f = query_value(query, "format");
  if (f.empty() || f == "html") return Format::kHtml;
  if (f == "csv") return Format::kCsv;
  if (f == "json") return Format::kJson;
  bad_input("format", "\"" + f.substr(0, 40) + "\" is not a format: html, csv or json");
}

void check_known_params(const Params& query, const std::vector<std::string>& known) {
  for (const auto& [name, value] : query) {
    // An emptied field of a resubmitted form filters nothing: no reason to refuse it.
    if (value.empty() || std::find(known.begin(), known.end(), name) != known.end()) continue;
    std::string takes;
    for (const std::string& k : known) takes += (takes.empty() ? "" : ", ") + k;
    bad_input(name.substr(0, 40), "not a parameter of this page (it takes " +
                                      (takes.empty() ? std::string("none") : takes) +
                                      "); the runs of a station, verdict or setting: /runs?" +
                                      "station=…&verdict=…&setting=…");
  }
}

void check_known_serial(const History& history, const std::string& serial,
                        const std::string& field) {
  try {
    history.repo->history(serial, 1);
  } catch (const db::history::NotFound& e) {
    const std::vector<std::string> near = suggestions_in(e.what());
    std::string html, text;
    for (const std::string& s : near) {
      html += (html.empty() ? "" : " or ") + unit_link(s);
      text += (text.empty() ? "" : " or ") + s;
    }
    const std::string message = "No unit with serial number \"" + serial +
                                "\" in this history (unknown serial)" +
                                (near.empty() ? "" : "; did you mean " + text + "?");
    throw PageErrorMore(404, field, message,
                        near.empty() ? std::string()
                                     : "<p id='suggestion'>Did you mean " + html +
                                           "? (serial numbers are compared exactly, case "
                                           "included)</p>\n");
  }
}

/// 404 for a station no run names, with the stations that differ from it only in case.
void check_known_station(const History& history, const std::string& station) {
  if (history.repo->station_run_count(station, std::nullopt) > 0) return;
  std::string near;
  auto lower = [](std::string s) {
    for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return s;
  };
  for (const auto& c : history.stats->verdict_counts_per_station({}))
    if (lower(c.station) == lower(station)) near += (near.empty() ? "" : " or ") + c.station;
  throw PageError(404, "station",
                  "station: unknown station: no run of station \"" + station +
                      "\" in this history" + (near.empty() ? "" : "; did you mean " + near + "?"));
}

std::string request_form(const std::string& path, const Params& query, const std::string& intro) {
  std::vector<std::string> fields;
  for (const auto& [p, names] : page_params())
    if (p == path) fields = names;
  if (fields.empty()) return "";
  for (const auto& kv : query)  // the faulty parameter too: it is what needs correcting
    if (kv.first != "format" && std::find(fields.begin(), fields.end(), kv.first) == fields.end())
      fields.push_back(kv.first);
  std::string s = "<form class='filters' id='request-form' action='" + esc(path) +
                  "' method='get'>\n<p class='muted'>" + esc(intro) + "</p>\n";
  for (const std::string& f : fields) {
    const auto it = query.find(f);
    s += "<label>" + esc(f) + " <input name='" + esc(f) + "' size='16' value='" +
         esc(it == query.end() ? "" : it->second) + "'></label>\n";
  }
  return s + "<button type='submit'>Send</button></form>\n";
}

}  // namespace imucal::tools::stationweb
