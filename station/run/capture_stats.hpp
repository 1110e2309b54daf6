#pragma once
// Counters of the daemon's IMU capture (station/run/capture.hpp): what the CAN channel and the
// frame decoder saw, how many archive rows were written, filled or marked at rest. Reported live in
// the daemon's status JSON, stored per run in the database (RunRecord::capture_json) and in the run
// archive's run.toml [capture] section (db/archive/FORMAT.md), all under the same names.
#include <cstdint>
#include <nlohmann/json.hpp>

#include "db/archive/run_archive.hpp"
#include "drivers/imu/imu_codec.hpp"

namespace imucal::station::run {

struct CaptureStats {
  uint64_t frames_received = 0, frames_logged = 0;  ///< all frames read / written to capture.log
  uint64_t frames_foreign = 0, frames_error = 0, frames_malformed = 0, frames_duplicate = 0,
           frames_out_of_order = 0, frames_discarded = 0, rx_overflow = 0;  ///< decoder + channel
  uint64_t samples_decoded = 0, samples_lost = 0, samples_corrupt = 0, samples_incomplete = 0,
           samples_late = 0;
  uint64_t samples_filled = 0;   ///< rows interpolated across lost samples
  uint64_t max_gap_samples = 0;  ///< longest run of consecutive lost samples
  uint64_t imu_resets = 0;
  uint64_t rows_written = 0;  ///< imu.csv == table.csv rows
  uint64_t rest_samples = 0;  ///< rows with at_rest = 1

  friend bool operator==(const CaptureStats& a, const CaptureStats& b);
  friend bool operator!=(const CaptureStats& a, const CaptureStats& b) { return !(a == b); }
};

/// The decoder's frame and sample counters into `stats` (frames_foreign … samples_late,
/// imu_resets); the others are left as they are.
void set_decoder_counters(CaptureStats& stats, const drivers::imu::DecoderCounters& decoder);

/// JSON object with one integer member per counter (the names above).
nlohmann::json to_json(const CaptureStats& stats);
/// Inverse of to_json. Strict: every counter present as a non-negative integer, no other members;
/// otherwise std::invalid_argument naming the member ("capture stats: field 'rows_written': ...").
CaptureStats capture_stats_from_json(const nlohmann::json& j);

/// The run.toml [capture] section for these counters.
db::archive::CaptureInfo to_capture_info(const CaptureStats& stats, bool complete);
/// The counters of a run.toml [capture] section.
CaptureStats capture_stats_from_info(const db::archive::CaptureInfo& info);

}  // namespace imucal::station::run
