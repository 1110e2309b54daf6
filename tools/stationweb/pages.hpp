#pragma once
// stationweb's pages, each a function of the history and the request's path or query (no HTTP
// types here: tools/stationweb/server.cpp maps URLs to them). A page throws PageError for bad
// input (400, naming the field) or an unknown serial or run (404); db::history::DbError escapes
// only for the database's own failures.
//
//   /                  index_page: the newest runs of every unit (?limit=N, 1..500, default 50)
//   /unit?serial=SN    unit_search: the serial checked, then a redirect to /unit/SN
//   /unit/SN           unit_page: the unit's history and its parameters' trend (SVG, ±1σ/±3σ)
//   /run/ID            run_page: what `stationctl show ID` shows, as a page
//   /fleet?...         fleet_page: runs per station per day, verdicts per station, and the
//                      distribution of one parameter per station (since, until, station, serial,
//                      param), opening with the flagged stations of the signature week
//   /signatures?...    signatures_page: station signatures of a period (since, until; default the
//                      7 days up to the newest run's day), flagged stations with cause and runs
//   /signatures/trend?... signature_trend_page: the signatures period by period (since, until,
//                      period_days; default 12 weeks up to the newest run's day), as a picture
#include <map>
#include <string>
#include <vector>

#include "tools/stationweb/history_source.hpp"
#include "tools/stationweb/html.hpp"

namespace imucal::tools::stationweb {

/// A request's query parameters (httplib::Params has this type).
using Params = std::multimap<std::string, std::string>;

std::string index_page(const History& history, const Params& query);
/// The serial of /unit?serial=SN, validated (400 naming "serial" otherwise).
std::string unit_search(const Params& query);
std::string unit_page(const History& history, const std::string& serial);
std::string run_page(const History& history, const std::string& run_id_text);
std::string fleet_page(const History& history, const Params& query);
std::string signatures_page(const History& history, const Params& query);
std::string signature_trend_page(const History& history, const Params& query);
/// The flagged stations of the default signature window (the week up to the newest run's day), as
/// the banner the fleet page opens with ("" for an empty history).
std::string signatures_banner(const History& history);

/// The value of query parameter `name`, or "" when absent; 400 if it is given twice.
std::string query_value(const Params& query, const std::string& name);
/// The serial rule (db/history/serial_number.hpp) as a 400 naming `field`.
void check_serial(const std::string& serial, const std::string& field);

// ----- Issue #52 (QA pages): data downloads, run lists, comparison, forgiving search ------------
//   /?format=csv|json, /unit/SN?format=csv|json   the page's run list as data
//   /runs?station=&serial=&verdict=&setting=&since=&until=&param=&limit=&format=
//                      runs_page: the runs behind a fleet bar, count or distribution (same filters)
//   /compare?a=N&b=M&method=&format=   compare_page: two runs' parameters side by side, Δ in σ

/// What a route answers: the body, its media type and, for a download, its file name.
struct Reply {
  Reply() = default;
  Reply(std::string b, std::string type = "text/html; charset=utf-8", std::string file = {})
      : body(std::move(b)), content_type(std::move(type)), filename(std::move(file)) {}
  std::string body;
  std::string content_type = "text/html; charset=utf-8";
  std::string filename;  ///< "" for a page; else Content-Disposition: attachment
};

/// A refusal whose error page adds HTML of its own after the message (suggestion links); the server
/// appends `more_html` and the request's form (request_form) to the error page.
struct PageErrorMore : PageError {
  PageErrorMore(int status_code, std::string field_name, const std::string& message,
                std::string html)
      : PageError(status_code, std::move(field_name), message), more_html(std::move(html)) {}
  std::string more_html;
};

/// ?format=: html (absent), csv or json; 400 naming "format" otherwise.
enum class Format { kHtml, kCsv, kJson };
Format parse_format(const Params& query);

/// 400 naming the first query parameter this page does not take (and what it takes): a typo or a
/// filter of another page must not silently list everything (issue #52 item 8).
void check_known_params(const Params& query, const std::vector<std::string>& known);
/// 404 "unknown serial" for a valid serial the history holds no unit of, with the units that
/// differ from it only in case as links ("did you mean SN-0008?").
void check_known_serial(const History& history, const std::string& serial,
                        const std::string& field);
/// 404 "unknown station" for a station no run names, with those differing only in case.
void check_known_station(const History& history, const std::string& station);
/// Leading and trailing blanks (a pasted " SN-0008 ") removed.
std::string trimmed(const std::string& text);
/// The request's own parameters as an editable form (values as given, the faulty one too), for
/// an error page of a page that takes a query; "" for other paths.
std::string request_form(const std::string& path, const Params& query,
                         const std::string& intro = "Your request, to correct and send again:");

Reply index_reply(const History& history, const Params& query);
Reply unit_reply(const History& history, const std::string& serial, const Params& query);
Reply runs_reply(const History& history, const Params& query);
Reply compare_reply(const History& history, const Params& query);
/// /signatures and /signatures/trend with ?format=csv|json (the report stationctl stations
/// --signatures --json prints; CSV: a row per station, or per station and period).
Reply signatures_reply(const History& history, const Params& query);
/// /fleet, refusing parameters it does not take, with ?format=csv|json (its tables as data).
Reply fleet_reply(const History& history, const Params& query);
Reply signature_trend_reply(const History& history, const Params& query);
/// /run/ID, refusing parameters it does not take, with ?format=json (`stationctl show ID --json`)
/// or csv (its parameters, a row per method and parameter, SI values).
Reply run_reply(const History& history, const std::string& run_id_text, const Params& query);

}  // namespace imucal::tools::stationweb
