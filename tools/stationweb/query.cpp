// Query parameters and the checks every page shares.
#include "db/history/serial_number.hpp"
#include "tools/stationweb/html.hpp"
#include "tools/stationweb/pages.hpp"

namespace imucal::tools::stationweb {

std::string query_value(const Params& query, const std::string& name) {
  const auto range = query.equal_range(name);
  if (range.first == range.second) return "";
  if (std::next(range.first) != range.second) bad_input(name, "given more than once");
  return range.first->second;
}

void check_serial(const std::string& serial, const std::string& field) {
  if (const auto problem = db::history::serial_problem(serial)) bad_input(field, *problem);
}

std::string unit_search(const Params& query) {
  const std::string serial = trimmed(query_value(query, "serial"));  // a pasted " SN-0008 "
  if (serial.empty()) bad_input("serial", "no serial number given");
  check_serial(serial, "serial");
  return serial;
}

}  // namespace imucal::tools::stationweb
