#pragma once
// QA's aggregate questions over a calibration history (issue #24 item 4, the fleet pages of
// stationweb): runs per station per day, verdict counts per station, and the distribution of one
// AINS parameter per station. Backend-neutral like db/history/repository.hpp:
// db/history/sqlite_fleet_stats.hpp answers them over a station's SQLite file, and the PostgreSQL
// fleet store implements the same interface; stationweb's pages only see this header.
//
// Every implementation must give the same numbers for the same rows, so the definitions are here:
//   * a run belongs to a filter when since_ms <= started_at_ms < until_ms (each bound optional),
//     its station equals `station` exactly (if given), its unit's serial equals `serial` (if
//     given), its setting equals `setting` (if given: factory, land, sea) and its verdict is one of
//     `verdict` (if given: one or several comma-separated; "live" for a run without one). A serial
//     that names no unit matches nothing (no error);
//   * one capture is counted once (issue #52): a run and the reprocesses reached from it through
//     reprocessed_from are one capture (the same archive calibrated again), and only its newest
//     run — the highest station-local run id — stands for it in runs_per_station_day,
//     verdict_counts_per_station and param_distribution; the filter applies to that run
//     (superseded_runs()). Without it a reprocessed capture counted twice in the verdict rates;
//   * a run's day is its UTC calendar day: floor(started_at_ms / 86 400 000) days since
//     1970-01-01 (utc_day());
//   * verdicts are the run's (RunRecord::verdict, stored at its end): PASS, REVIEW, FAILED — the
//     unit's own outcomes, what its yield counts — and STATION-FAULT, ABORTED, INTERRUPTED, which
//     say nothing about the unit (issue #50: a station's faults are counted per station, never as a
//     unit's failure); a run still live has none and is counted as live;
//   * a parameter's distribution takes the AINS calibration of every matching run that has one
//     (whatever its verdict), the value in SI units as stored in the parameter-set JSON — except
//     where that result does not determine the parameter (CalibrationRecord::unobservable lists
//     it: its stored value is a placeholder, e.g. ς of a field run). A parameter that depends on
//     the body frame (frame_dependent(): the off-diagonal misalignments accel_M[i][j] and
//     gyro_M[i][j], i != j, which a rotation of the frame moves) takes only the results in the
//     housing frame: a field result is in the accelerometer-symmetric frame (calib/ains/ains.cpp,
//     calibrations.body_frame), its misalignments are relative to another frame and cannot be
//     pooled with a factory result's; those left out are counted per station (other_frame). count,
//     mean, sample standard deviation (n - 1; 0 for one value), min, max and the quartiles by
//     linear interpolation between order statistics (R's type 7, PostgreSQL's percentile_cont):
//     q(p) = x[floor(h)] + (h - floor(h)) (x[floor(h) + 1] - x[floor(h)]), h = (n - 1) p, x sorted
//     ascending from index 0 (summarize()).
// Results come sorted: by station (byte order), then day.
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "calib/core/param_set.hpp"
#include "db/history/repository.hpp"

namespace imucal::db::history {

struct FleetFilter {
  std::optional<TimestampMs> since_ms;  ///< started_at_ms >= since_ms
  std::optional<TimestampMs> until_ms;  ///< started_at_ms < until_ms
  std::optional<std::string> station;   ///< exact station name
  std::optional<std::string> serial;    ///< exact serial (db/history/serial_number.hpp rule)
  std::optional<std::string> setting;   ///< "factory", "land" or "sea" (runs.setting)
  /// A RunVerdict's text, or "live" (no verdict yet); several comma-separated: any of them.
  std::optional<std::string> verdict;
};

/// A reprocess and the run it names (reprocessed_from), each with the history's id and its
/// order of creation at its station (a station's SQLite: the id itself; the fleet store: the
/// station's own run id), for superseded_runs().
struct ReprocessLink {
  RunId run = 0, origin = 0;
  std::int64_t run_seq = 0, origin_seq = 0;
};

struct StationDayCount {
  std::string station;
  std::int64_t day = 0;  ///< UTC days since 1970-01-01 (utc_day)
  std::int64_t runs = 0;
};

struct StationVerdictCounts {
  std::string station;
  std::int64_t pass = 0;
  std::int64_t review = 0;
  std::int64_t failed = 0;         ///< the unit's FAILED: its data or its calibration failed
  std::int64_t station_fault = 0;  ///< STATION-FAULT: table, CAN bus, disk, daemon
  std::int64_t aborted = 0;        ///< ABORTED: an operator's `run abort`, or stationd stopped
                                   ///< during the run (stopped_by_daemon)
  std::int64_t interrupted = 0;    ///< INTERRUPTED: the daemon stopped or died mid-run
  std::int64_t live = 0;           ///< runs without a verdict yet
  /// The runs whose outcome is the unit's own (PASS, REVIEW, FAILED): what yield is a share of.
  std::int64_t unit_outcomes() const { return pass + review + failed; }
  std::int64_t total() const {
    return unit_outcomes() + station_fault + aborted + interrupted + live;
  }
};

/// One station's values of one parameter (SI units), see the file comment for the definitions.
struct ParamSummary {
  std::string station;
  std::int64_t count = 0;
  double mean = 0, std_dev = 0, min = 0, q1 = 0, median = 0, q3 = 0, max = 0;
  /// A frame-dependent parameter: the station's matching results left out because they are not
  /// in the housing frame (field runs). A station whose results are all left out appears with
  /// count 0.
  std::int64_t other_frame = 0;
};

/// One AINS result for the station signatures (issue #25,
/// calib/studies/fleet/station_signature.hpp).
struct AinsResultRow {
  RunId run_id = 0;        ///< in the history read (the store's own id in the fleet store)
  RunId local_run_id = 0;  ///< the station's own id of the run (what its stationctl names)
  std::string station;
  std::string serial;
  std::string sequence_name;
  TimestampMs started_at_ms = 0;
  calib::core::ParamSet value;  ///< the AINS estimate, SI
  calib::core::ParamSet sigma;  ///< its 1-σ
};

class FleetStats {
 public:
  virtual ~FleetStats() = default;
  /// Matching runs counted per (station, UTC day); only pairs with runs appear.
  virtual std::vector<StationDayCount> runs_per_station_day(const FleetFilter& filter) const = 0;
  /// Matching runs counted per station and verdict; only stations with runs appear.
  virtual std::vector<StationVerdictCounts> verdict_counts_per_station(
      const FleetFilter& filter) const = 0;
  /// The AINS value of parameter `param_index` (calib::core::param_info order, 0..26) per station,
  /// over the matching runs with an AINS calibration; stations without one do not appear.
  virtual std::vector<ParamSummary> param_distribution(int param_index,
                                                       const FleetFilter& filter) const = 0;
  /// The runs of one table run (several units on one fixture, schema v6): the run
  /// `table_run_id` itself and every run naming it as its table run, ascending id. A run of its
  /// own gives just itself; an unknown id gives nothing.
  virtual std::vector<RunId> table_run_members(RunId table_run_id) const = 0;
  /// The AINS results of the matching factory table runs that determine every parameter, as
  /// stored, ascending run id — what a station error would have moved. Left out: field runs (no
  /// table, no surveyed gravity), results with an undetermined term, reprocessed runs (the
  /// same data again; their originals stand for them — unless the original has no result, see
  /// signature_stand_ins()), and ended runs whose verdict is not the unit's own (STATION-FAULT,
  /// ABORTED, INTERRUPTED: issue #50).
  virtual std::vector<AinsResultRow> ains_results(const FleetFilter& filter) const = 0;
  /// Every reprocess of the history with the run it names (any window), ascending run: what
  /// superseded_runs() takes, for a list of runs that must count what the aggregates count and
  /// say which run a reprocess replaced (stationweb's run lists).
  virtual std::vector<ReprocessLink> reprocess_links() const = 0;
};

/// The reprocesses that stand for their capture in ains_results(): a capture (a run and the
/// reprocesses reached from it, as in superseded_runs()) is stood for by its original when the
/// original has a usable result, otherwise by the first of its reprocesses (by creation order)
/// that has one. `usable`: the runs among `links` with an AINS result ains_results() would take,
/// not calibrated from a partial archive (a partial capture lacks part of the sequence the
/// signature's responses are measured on). Without it a capture the daemon interrupted — its
/// only result a reprocess — was left out of the signatures, and its unit with it (issue #52).
std::vector<RunId> signature_stand_ins(const std::vector<ReprocessLink>& links,
                                       const std::vector<RunId>& usable);

/// The parameter's flat index (calib::core::param_info) from its name in the parameter-set JSON,
/// e.g. "gyro_bias_radps[2]" or "accel_M[0][1]"; InvalidInput naming the accepted form otherwise.
int param_index(const std::string& name);

/// Whether the parameter's value depends on the body frame a result is expressed in: the
/// off-diagonal misalignments accel_M[i][j] and gyro_M[i][j], i != j (calib/core/body_frame.hpp:
/// a rotation R of the frame turns I + M into (I + M) Rᵀ, which moves them to first order).
bool frame_dependent(int param_index);

/// The verdicts of a filter's `verdict` text (comma-separated, each trimmed), in the order given.
std::vector<std::string> verdict_list(const std::string& text);

/// floor(t_ms / 86 400 000): the UTC day of a time, also before 1970.
std::int64_t utc_day(TimestampMs t_ms);

/// The statistics of the file comment over `values` (sorted in place); count 0 for none.
ParamSummary summarize(std::vector<double>& values);

/// InvalidInput naming the field if a filter value breaks a rule: since after until, a malformed
/// serial, a station name longer than 200 bytes or with control characters, a setting other than
/// factory/land/sea, a verdict other than a RunVerdict's text or "live".
void validate_filter(const FleetFilter& filter);

/// The runs that do not stand for their capture (the file comment): of every capture that holds a
/// reprocess, each run but the newest (highest run_seq). `links` holds every reprocess of the
/// history (any window: a capture's newest run may lie outside it).
std::vector<RunId> superseded_runs(const std::vector<ReprocessLink>& links);

}  // namespace imucal::db::history
