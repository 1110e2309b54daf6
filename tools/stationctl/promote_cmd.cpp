#include "tools/stationctl/promote_cmd.hpp"

#include <iostream>

namespace imucal::tools::stationctl {

CLI::App* add_promote_command(CLI::App& app, PromoteArgs& a) {
  CLI::App* promote = app.add_subcommand(
      "promote", "QA: make a field run the unit's active parameters (needs the group)");
  promote->add_option("RUN_ID", a.run_id, "run id")->required()->check(CLI::PositiveNumber);
  promote->add_option("--reason", a.reason, "why (stored with the run, required)")
      ->required()
      ->check(text_check(station::control::kMaxReasonChars));
  promote->fallthrough();
  return promote;
}

int cmd_promote(const Target& t, const PromoteArgs& a, bool as_json) {
  ControlClient client = connect_or_fail(t);
  const json r =
      call(client, station::control::cmd::kPromote, {{"run_id", a.run_id}, {"reason", a.reason}});
  if (as_json)
    print_json(r);
  else
    std::cout << "run " << a.run_id << " promoted to the active parameters by "
              << text(r, "promoted_by") << " at " << text(r, "promoted_at") << "\n";
  return kOk;
}

}  // namespace imucal::tools::stationctl
