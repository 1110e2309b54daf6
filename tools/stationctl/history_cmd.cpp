#include "tools/stationctl/history_cmd.hpp"

#include "station/control/record_json.hpp"

namespace imucal::tools::stationctl {

CLI::App* add_history_command(CLI::App& app, HistoryArgs& a) {
  CLI::App* history = app.add_subcommand(
      "history", "the runs of a unit, newest first; without SN the newest runs of every unit");
  history->add_option("SN", a.serial, "serial number (default: every unit)");
  history->add_option("--limit", a.limit,
                      "at most N runs (default: all of a unit, the newest 20 of every unit)");
  history->add_option("--station", a.station, "only this station's runs");
  history->fallthrough();
  return history;
}

int cmd_history(const Target& t, const HistoryArgs& a, bool as_json) {
  json args = json::object();
  if (!a.serial.empty()) {
    check_serial(a.serial);
    args["serial"] = a.serial;
  }
  if (a.limit > 0) args["limit"] = a.limit;
  if (!a.station.empty()) args["station"] = a.station;
  return print_result(read_request(t, station::control::cmd::kHistory, args), as_json,
                      station::control::render_history_text);
}

}  // namespace imucal::tools::stationctl
