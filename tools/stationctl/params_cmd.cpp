#include "tools/stationctl/params_cmd.hpp"

#include "station/control/record_json.hpp"

namespace imucal::tools::stationctl {

CLI::App* add_params_command(CLI::App& app, ParamsArgs& a) {
  CLI::App* params = app.add_subcommand(
      "params",
      "the unit's active parameter set with 1-sigma (JSON for the INS) and, under \"source\", the "
      "run it comes from");
  params->add_option("SN", a.serial, "serial number")->required();
  params->add_flag("--bare", a.bare,
                   "leave \"source\" out: only the five schema keys and sigma, for a loader that "
                   "accepts nothing else");
  params->fallthrough();
  return params;
}

int cmd_params(const Target& t, const ParamsArgs& a, bool as_json) {
  check_serial(a.serial);
  json params = read_request(t, station::control::cmd::kParams, {{"serial", a.serial}});
  if (a.bare) params.erase("source");
  return print_result(params, as_json, station::control::render_params_text);
}

}  // namespace imucal::tools::stationctl
