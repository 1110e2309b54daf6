#include "tools/stationctl/show_cmd.hpp"

#include "station/control/record_json.hpp"

namespace imucal::tools::stationctl {

CLI::App* add_show_command(CLI::App& app, ShowArgs& a) {
  CLI::App* show = app.add_subcommand("show", "everything stored about a run");
  show->add_option("RUN_ID", a.run_id, "run id")->required()->check(CLI::PositiveNumber);
  show->fallthrough();
  return show;
}

int cmd_show(const Target& t, const ShowArgs& a, bool as_json) {
  return print_result(read_request(t, station::control::cmd::kShow, {{"run_id", a.run_id}}),
                      as_json, station::control::render_show_text);
}

}  // namespace imucal::tools::stationctl
