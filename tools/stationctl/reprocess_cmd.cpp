#include "tools/stationctl/reprocess_cmd.hpp"

#include <cstdio>
#include <iostream>
#include <set>
#include <string>

#include "station/control/record_json.hpp"
#include "tools/stationctl/run_cmd.hpp"

namespace imucal::tools::stationctl {

namespace {

json reprocess_args(db::history::RunId run_id, const ReprocessArgs& a) {
  json args = {{"run_id", run_id}};
  if (a.partial) args["partial"] = true;
  if (a.gravity_mps2) args["gravity_mps2"] = *a.gravity_mps2;
  return args;
}

/// The command that reprocesses `rest` with the same options: what a stopped batch leaves to do.
std::string reprocess_command(const std::vector<db::history::RunId>& rest, const ReprocessArgs& a) {
  std::string cmd = "stationctl reprocess";
  for (const db::history::RunId id : rest) cmd += " " + std::to_string(id);
  if (a.partial) cmd += " --partial";
  if (a.gravity_mps2) {
    char g[32];
    std::snprintf(g, sizeof g, "%.10g", *a.gravity_mps2);
    cmd += std::string(" --gravity-mps2 ") + g;
  }
  return cmd;
}

void check_given_once(const std::vector<db::history::RunId>& run_ids) {
  std::set<db::history::RunId> seen;
  for (const db::history::RunId id : run_ids)
    if (!seen.insert(id).second)
      throw Failure{kBadInput, "reprocess: run " + std::to_string(id) + " is given twice"};
}

/// Several runs (a flagged station's, issue #25): the daemon calibrates one at a time, so each is
/// started once the one before has ended. One line per run, old -> new and its outcome; a refusal
/// or an interruption stops the batch and says which runs are left, with the command that goes on.
/// Exit code: 0 only when every new run is done + PASS.
int reprocess_batch(const Target& t, const ReprocessArgs& a, bool as_json) {
  check_given_once(a.run_ids);
  ControlClient client = connect_or_fail(t);
  json done = json::array();
  int code = kOk;
  for (std::size_t i = 0; i < a.run_ids.size(); ++i) {
    const db::history::RunId old_id = a.run_ids[i];
    const std::vector<db::history::RunId> rest(a.run_ids.begin() + static_cast<std::ptrdiff_t>(i),
                                               a.run_ids.end());
    const std::string left = " (reprocessed " + std::to_string(i) + " of " +
                             std::to_string(a.run_ids.size()) +
                             "; to go on: " + reprocess_command(rest, a) + ")";
    json r;
    try {
      r = call(client, station::control::cmd::kReprocess, reprocess_args(old_id, a));
    } catch (Failure& f) {
      f.message = "run " + std::to_string(old_id) + ": " + f.message + left;
      throw;
    }
    if (!as_json)
      std::cerr << "[" << i + 1 << "/" << a.run_ids.size() << "] run " << old_id
                << " reprocessing as run " << text(r, "run_id", "?") << "\n";
    json run;
    const int c = wait_for_run(t, client, r.at("run_id").get<db::history::RunId>(), as_json, &run);
    if (c == kStoppedFollowing) {
      std::cerr << "stationctl: the batch stopped" << left << "\n";
      return c;
    }
    if (c != kOk) code = c;
    done.push_back({{"reprocessed", old_id}, {"run", run}});
    if (!as_json)
      std::cout << "run " << old_id << " -> " << station::control::outcome_line(run) << "\n"
                << std::flush;
  }
  if (as_json)
    print_json(json{{"runs", done}});
  else if (a.gravity_mps2)
    std::cerr << "the new runs become their units' active parameters only once QA promotes them "
                 "(stationctl promote RUN_ID --reason TEXT)\n";
  return code;
}

}  // namespace

CLI::App* add_reprocess_command(CLI::App& app, ReprocessArgs& a) {
  CLI::App* reprocess = app.add_subcommand(
      "reprocess",
      "recalibrate stored runs from their archives into new runs (needs the group); several "
      "RUN_IDs (a station signature's runs) are reprocessed one after another, each followed to "
      "its end");
  reprocess->add_option("RUN_ID", a.run_ids, "run id(s)")->required()->check(CLI::PositiveNumber);
  reprocess->add_flag("--wait", a.wait, "follow the new run to its end (always, for several)");
  reprocess->add_flag("--partial", a.partial,
                      "calibrate an incomplete archive (aborted, interrupted or failed capture) "
                      "anyway: stored REVIEW at best, never the unit's active parameters");
  reprocess->add_option("--gravity-mps2", a.gravity_mps2,
                        "calibrate with this surveyed gravity (m/s², 9.7-9.9) instead of the "
                        "archive's: a station whose signature showed a wrong gravity, corrected "
                        "(issue #25); the new run says so and, like an import, becomes the "
                        "unit's active parameters only when QA promotes it");
  reprocess->fallthrough();
  return reprocess;
}

int cmd_reprocess(const Target& t, const ReprocessArgs& a, bool as_json) {
  if (a.run_ids.size() > 1) return reprocess_batch(t, a, as_json);
  const db::history::RunId run_id = a.run_ids.at(0);
  ControlClient client = connect_or_fail(t);
  const json r = call(client, station::control::cmd::kReprocess, reprocess_args(run_id, a));
  return started(t, client, r, "reprocesses run " + std::to_string(run_id), a.wait, as_json);
}

}  // namespace imucal::tools::stationctl
