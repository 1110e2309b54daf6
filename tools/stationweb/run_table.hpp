#pragma once
// The table of runs the index, the unit page and /runs share: the columns of `stationctl history`
// (station/control/record_json.hpp's render_history_text) — run (marked * when reprocessed from
// another run, ^ when promoted by QA), [serial,] start time, setting (with "imported" for an
// imported field run), state, verdict, cross-check, station, slot, sequence, operator, duration,
// gap cell, reason — so an imported field run never looks like a factory PASS (issue #52 item 7).
// Each row carries its run's facts in data attributes (data-run-id, data-serial, data-state,
// data-verdict, data-station, data-started-ms, data-setting, data-operator, data-duration-s,
// data-reprocessed-from, data-origin) for scripts and tests.
//
// The same list as data: run_list_json is `stationctl history --json`'s object
// (station/control/record_json.hpp history_result), run_list_csv one line per run with the
// table's columns (SI seconds, ISO times).
#include <optional>
#include <string>
#include <vector>

#include "db/history/repository.hpp"
#include "tools/stationweb/history_source.hpp"

namespace imucal::tools::stationweb {

/// <table id='`id`'> of `runs` in the given order; `with_serial` adds the serial column;
/// `extra_header`/`extra_cells` (one per run, HTML) add a last column (/runs' parameter value).
std::string run_table(const std::vector<db::history::RunRecord>& runs, bool with_serial,
                      const std::string& id, const std::string& extra_header = {},
                      const std::vector<std::string>& extra_cells = {});

/// The same table with each run's reprocess links (issue #52, the audit's F10), read from
/// `history`'s reprocesses: a reprocessed run says which run reprocessed it and, at the end of a
/// chain, which run decides ("→ run 22, newest run 23"); a reprocess says which run it reprocessed
/// ("reprocess of run 21"). The rows carry data-reprocessed-as (the direct reprocesses) and
/// data-capture-newest (the capture's newest run, where it is another).
std::string run_table(const History& history, const std::vector<db::history::RunRecord>& runs,
                      bool with_serial, const std::string& id, const std::string& extra_header = {},
                      const std::vector<std::string>& extra_cells = {});

/// <span class='PASS'>PASS</span> (REVIEW, FAILED), or "-" for a live run.
std::string verdict_html(const std::optional<db::history::RunVerdict>& verdict);

/// history_result(serial, runs, total) as stationctl prints it with --json ("" serial: null).
std::string run_list_json(const std::string& serial,
                          const std::vector<db::history::RunRecord>& runs, std::size_t total);
/// A header line and one line per run (RFC 4180 quoting); `extra_header`/`extra_values` add a
/// last column.
std::string run_list_csv(const std::vector<db::history::RunRecord>& runs,
                         const std::string& extra_header = {},
                         const std::vector<std::string>& extra_values = {});
/// <p class='downloads'>: `target` (a page's URL with its query) with format=csv and format=json.
std::string download_links(const std::string& target);
/// One CSV field, quoted when it holds a comma, a quote or a line break.
std::string csv_field(const std::string& text);

}  // namespace imucal::tools::stationweb
