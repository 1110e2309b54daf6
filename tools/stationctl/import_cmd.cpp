#include "tools/stationctl/import_cmd.hpp"

#include <filesystem>
#include <iostream>

#include "tools/stationctl/run_cmd.hpp"

namespace imucal::tools::stationctl {

CLI::App* add_import_command(CLI::App& app, ImportArgs& a) {
  CLI::App* import = app.add_subcommand(
      "import",
      "add a field (land/sea) or other station's run archive to its unit's history and calibrate "
      "it with its setting (needs the group); it keeps the archive's recorded start and end, never "
      "becomes active unless promoted, and an archive already stored is refused");
  import->add_option("DIR", a.dir, "run archive directory (imucal simulate/calibrate format)")
      ->required();
  import->add_flag("--wait", a.wait, "follow the calibration to its end");
  import->fallthrough();
  return import;
}

/// The daemon reads the archive itself, so the path is made absolute here (the daemon's working
/// directory is not the user's).
int cmd_import(const Target& t, const ImportArgs& a, bool as_json) {
  std::error_code ec;
  const std::string abs = std::filesystem::absolute(a.dir, ec).lexically_normal().string();
  if (ec || !std::filesystem::is_directory(abs))
    throw Failure{kBadInput, a.dir + ": no such run archive directory"};
  ControlClient client = connect_or_fail(t);
  const json r = call(client, station::control::cmd::kImport, {{"dir", abs}});
  const std::string head = "run " + text(r, "run_id", "?") + ": imported " + text(r, "setting") +
                           " run of " + text(r, "serial") + " from " + abs;
  if (!a.wait) {
    if (as_json)
      print_json(r);
    else
      std::cout << head << "\n";
    return kOk;
  }
  if (!as_json) std::cerr << head << "\n";
  return wait_for_run(t, client, r.at("run_id").get<db::history::RunId>(), as_json);
}

}  // namespace imucal::tools::stationctl
