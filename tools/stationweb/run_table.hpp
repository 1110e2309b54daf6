#pragma once
// The table of runs the index and the unit page share (the columns of `stationctl history`): run,
// [serial,] start time, state, verdict, cross-check, station, slot, sequence, gap cell. Each row
// carries its run's facts in data attributes (data-run-id, data-serial, data-state, data-verdict,
// data-station, data-started-ms) for scripts and tests.
#include <string>
#include <vector>

#include "db/history/repository.hpp"

namespace imucal::tools::stationweb {

/// <table id='`id`'> of `runs` in the given order; `with_serial` adds the serial column.
std::string run_table(const std::vector<db::history::RunRecord>& runs, bool with_serial,
                      const std::string& id);

/// <span class='PASS'>PASS</span> (REVIEW, FAILED), or "-" for a live run.
std::string verdict_html(const std::optional<db::history::RunVerdict>& verdict);

}  // namespace imucal::tools::stationweb
