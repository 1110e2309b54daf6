#pragma once
// What QA does next with a run (issue #52 item 6: a REVIEW run said why, not what to do): one
// primary step — a command to run or a decision to take — and a line per reason, from the run's
// verdict, its reasons' sources (cross-check, limits, gap, partial archive, field, error, aborted,
// interrupted), whether its capture is complete, and whether it has been reprocessed already.
//
// <div id='next-step' data-action='A' data-command='C' data-decides='N'>: A is one of none, wait,
// see-reprocess, promote, diagnose, remount, rerun, reprocess, decide; C the command ("" for a
// decision); N the run that decides for see-reprocess ("" otherwise).
#include <optional>
#include <string>
#include <vector>

#include "db/history/repository.hpp"

namespace imucal::tools::stationweb {

struct NextStep {
  std::string action;   ///< see above
  std::string command;  ///< e.g. "stationctl reprocess 12"; "" where the step is a decision
  std::string text;     ///< for people, plain text
  db::history::RunId decides = 0;  ///< see-reprocess: the run that decides (newest of the chain)
};

/// The primary step, then one per further reason (deduplicated by action).
/// `reprocesses`: the runs reprocessed from this one (newest first); `capture_complete`: the run's
/// capture counters say complete (nullopt: none stored); `newest`: the newest run of the
/// reprocess chain from this one (the newest reprocess of its newest reprocess ...), which decides
/// (nullopt: reprocesses.front()).
std::vector<NextStep> next_steps(
    const db::history::RunRecord& run, const std::vector<db::history::RunRecord>& reprocesses,
    std::optional<bool> capture_complete,
    const std::optional<db::history::RunRecord>& newest = std::nullopt);

/// The section: <div id='next-step'> with the primary step, the others as a list.
std::string next_step_section(const std::vector<NextStep>& steps);

}  // namespace imucal::tools::stationweb
