// "/": the newest runs of every unit, and the serial search.
#include <cctype>

#include "tools/stationweb/html.hpp"
#include "tools/stationweb/pages.hpp"
#include "tools/stationweb/run_table.hpp"

namespace imucal::tools::stationweb {

namespace {

constexpr std::size_t kDefaultLimit = 50, kMaxLimit = 500;

std::size_t parse_limit(const std::string& text) {
  if (text.empty()) return kDefaultLimit;
  bool digits = text.size() <= 4;
  for (char c : text) digits = digits && std::isdigit(static_cast<unsigned char>(c));
  const std::size_t n = digits ? std::stoul(text) : 0;
  if (n < 1 || n > kMaxLimit)
    bad_input("limit", "\"" + text.substr(0, 40) + "\" is not a whole number from 1 to " +
                           std::to_string(kMaxLimit));
  return n;
}

}  // namespace

Reply index_reply(const History& history, const Params& query) {
  check_known_params(query, {"limit", "format"});
  const Format format = parse_format(query);
  if (format == Format::kHtml) return {index_page(history, query)};
  const std::size_t limit = parse_limit(query_value(query, "limit"));
  const std::vector<db::history::RunRecord> runs = history.repo->recent_runs(limit);
  if (format == Format::kJson)
    return {run_list_json("", runs, history.repo->total_run_count()), "application/json",
            "recent-runs.json"};
  return {run_list_csv(runs), "text/csv; charset=utf-8", "recent-runs.csv"};
}

std::string index_page(const History& history, const Params& query) {
  const std::size_t limit = parse_limit(query_value(query, "limit"));
  const std::vector<db::history::RunRecord> runs = history.repo->recent_runs(limit);
  const std::size_t total = history.repo->total_run_count();
  std::string b = "<h1>Calibration history</h1>\n<p class='muted'>" + esc(history.label) +
                  ", read-only: <span id='total-runs' data-value='" + std::to_string(total) + "'>" +
                  std::to_string(total) + "</span> runs in all.</p>\n";
  b += "<form id='serial-search' action='/unit' method='get'><label>Serial number "
       "<input name='serial' size='24' required></label> <button type='submit'>Show the "
       "unit's history</button></form>\n";
  b += "<h2>Newest " + std::to_string(runs.size()) + " runs</h2>\n";
  if (runs.empty()) return page("Recent runs", b + "<p>No runs yet.</p>\n");
  b += run_table(history, runs, true, "recent-runs");
  b += download_links("/?limit=" + std::to_string(limit));
  if (total > runs.size())
    b += "<p class='muted'>Older runs: <a href='/?limit=" + std::to_string(kMaxLimit) +
         "'>the newest " + std::to_string(kMaxLimit) +
         "</a>, a unit's page, or the fleet pages.</p>\n";
  return page("Recent runs", b);
}

}  // namespace imucal::tools::stationweb
