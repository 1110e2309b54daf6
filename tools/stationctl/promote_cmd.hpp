#pragma once
// `stationctl promote RUN_ID --reason TEXT`: QA makes a field run the unit's active parameters
// (needs the group); recorded with the caller's user name.
#include <CLI/CLI.hpp>
#include <string>

#include "db/history/repository.hpp"
#include "tools/stationctl/connection.hpp"

namespace imucal::tools::stationctl {

struct PromoteArgs {
  db::history::RunId run_id = 0;
  std::string reason;
};

CLI::App* add_promote_command(CLI::App& app, PromoteArgs& args);
int cmd_promote(const Target& t, const PromoteArgs& a, bool as_json);

}  // namespace imucal::tools::stationctl
