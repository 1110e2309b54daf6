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

#include "tools/stationweb/history_source.hpp"

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

}  // namespace imucal::tools::stationweb
