#pragma once
// One row of the JSON/NDJSON export written straight into a text buffer (issue #11 item 3).
//
// The bytes are exactly those of nlohmann's compact dump of the row object (run_json(run) plus
// "calibration" and "crosscheck", db/history/export.hpp): keys in the same sorted order, numbers
// through nlohmann's own shortest round-trip formatter, strings escaped as nlohmann does. Building
// and printing a nlohmann object per row cost half of a 2·10⁵-row export in map nodes and
// allocations; this writer allocates only for the stored capture/diagnosis objects (parsed and
// re-printed, so that a damaged one is still reported) and for strings that need escaping.
// tests/db/export_row_writer_test.cpp holds it to nlohmann's output on hand-picked and random rows.
#include <string>

#include "db/history/repository.hpp"

namespace imucal::db::history {

/// Appends the row's JSON object (no newline). Throws what run_json/calibration_json throw:
/// Corrupt for a stored object that is not one, or a parameter set that is not finite or has a
/// negative σ; nlohmann's type_error for a string that is not UTF-8.
void append_export_row_json(std::string& out, const ExportRow& row);

}  // namespace imucal::db::history
