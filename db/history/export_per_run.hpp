#pragma once
// The export's second row shape (issue #50 item 4, `stationctl export --per-run`): one row per
// run, the calibration methods side by side, where the default shape (export.hpp) has one row per
// run and method (a factory run: two rows, AINS and NLSQ).
//
// CSV: the default shape's columns regrouped. The run's columns (kCsvRunColumns); then, for each
// method in the order ains, nlsq, legacy, its calibration columns without "method"
// (kCsvCalibrationColumns[1..]), its 27 parameters and their "sigma." columns, every name
// prefixed with the method: "ains.converged", "nlsq.accel_bias_mps2[0]",
// "ains.sigma.gyro_M[2][2]"; then the run's cross-check, capture and diagnosis columns. A method
// the run has no result of (legacy on a factory run; every method of a failed or aborted run)
// leaves its columns empty. The fields are the default shape's bytes, so the two shapes read the
// same numbers.
//
// JSON and NDJSON: one object per run, run_json(run) plus "calibrations": [calibration_json, ...]
// in method order (empty for a run without results) and "crosscheck" (or null).
#include <cstddef>
#include <ostream>
#include <string>

#include "db/history/repository.hpp"

namespace imucal::db::history {

/// The export in `format` ("csv", "json" or "ndjson"; InvalidInput otherwise), one row or object
/// per run; returns the number of runs. IoError if the stream fails.
std::size_t export_per_run(const Repository& repo, const ExportFilter& filter,
                           const std::string& format, std::ostream& out);

/// The export in the shape asked for: export_per_run with `per_run`, else export_history (a row
/// per run and method). The number of rows written.
std::size_t export_in_shape(const Repository& repo, const ExportFilter& filter,
                            const std::string& format, bool per_run, std::ostream& out);

}  // namespace imucal::db::history
