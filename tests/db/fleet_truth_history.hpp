#pragma once
// A history as QA met it in issue #52: factory runs of seven units at one station and one unit at
// another, a capture reprocessed once and one reprocessed twice (a chain), an imported land field
// run whose gyro bias is four orders of magnitude off the factory's, a station fault, an
// operator's abort, an interrupted run, a unit's FAILED, and a run whose NLSQ did not converge.
// Every row is kept as written, so a test computes the fleet pages' numbers from the rows by the
// rules of db/history/fleet_stats.hpp on its own (expected_counts, expected_values), apart from
// the code under test.
#include <map>
#include <optional>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "calib/core/calibration_input.hpp"
#include "calib/core/conventions.hpp"
#include "calib/core/param_set.hpp"
#include "db/history/fleet_stats.hpp"
#include "db/history/sqlite_repository.hpp"
#include "tests/db/fleet_history.hpp"
#include "tests/db/history_fixtures.hpp"

namespace imucal::db::test {

using namespace imucal::db::history;

struct TruthRow {
  RunId run_id = 0;
  std::string station, serial, setting = "factory";
  TimestampMs started_at_ms = 0;
  std::string verdict;  ///< as stored, "" live
  std::optional<RunId> reprocessed_from;
  std::optional<calib::core::ParamVector> ains;
  bool nlsq_converged = true;
};

inline TimestampMs truth_t0() { return parse_time_utc("2026-11-23T08:00:00Z"); }

/// The gyro z bias of the imported land run, deg/h (issue #52: −9 872 deg/h among ~0.01 deg/h).
constexpr double kFieldGyroZDegPerHour = -9872.0;

struct TruthWriter {
  SqliteRepository& repo;
  std::vector<TruthRow> rows;
  std::mt19937 rng{52};
  TimestampMs t = truth_t0();

  NewRun next(const std::string& station, const std::string& serial) {
    t += 1800000;  // every run its own half hour
    NewRun r = new_run(serial, t);
    r.station = station;
    return r;
  }
  /// Stores `run` finished by `c`; the row as the test counts it.
  TruthRow& add(const NewRun& run, RunCompletion c, const std::string& verdict) {
    TruthRow row;
    row.run_id = repo.create_run(run);
    row.station = run.station;
    row.serial = run.serial;
    row.started_at_ms = run.started_at_ms;
    row.setting = calib::core::setting_name(run.setting);
    row.reprocessed_from = run.reprocessed_from;
    row.verdict = verdict;
    c.ended_at_ms = run.started_at_ms + 600000;
    if (!c.calibrations.empty()) {
      row.ains = c.calibrations[0].params.to_vector();
      if (c.calibrations.size() > 1) row.nlsq_converged = c.calibrations[1].converged;
    }
    repo.finish_run(row.run_id, c);
    rows.push_back(row);
    return rows.back();
  }
  /// A factory completion with plausible AINS values (PASS or REVIEW), both methods converged.
  RunCompletion factory(int level, std::size_t station, bool review = false) {
    RunCompletion c = review ? review_completion(level + 10, 0) : pass_completion(level + 10, 0);
    c.calibrations[0] = fleet_ains(rng, level, station);
    c.calibrations[0].converged = true;
    c.calibrations[1].converged = true;
    return c;
  }
  RunCompletion ended(RunState state, const std::string& reason,
                      std::optional<RunVerdict> verdict = std::nullopt) {
    RunCompletion c;
    c.state = state;
    c.reason = reason;
    c.verdict = verdict;
    return c;
  }
};

/// Writes the history (its rows in the order written).
inline std::vector<TruthRow> write_truth_history(SqliteRepository& repo) {
  TruthWriter w{repo, {}};
  for (int u = 1; u <= 7; ++u)
    w.add(w.next("st-A", "U-" + std::to_string(u)), w.factory(u, 0, u == 5),
          u == 5 ? "REVIEW" : "PASS");
  w.add(w.next("st-A", "U-1"), w.factory(1, 0), "PASS");  // U-1 again: 8 runs, 7 units
  // U-2's capture reprocessed once; U-3's twice, the second reprocess of the first reprocess.
  for (const std::string serial : {"U-2", "U-3"}) {
    RunId origin = 0;
    for (const TruthRow& r : w.rows)
      if (r.serial == serial) origin = r.run_id;
    NewRun rp = w.next("st-A", serial);
    rp.reprocessed_from = origin;
    rp.archive_path = repo.show(origin).run.archive_path;
    const RunId first = w.add(rp, w.factory(serial == "U-2" ? 2 : 3, 0), "PASS").run_id;
    if (serial == "U-3") {
      rp = w.next("st-A", serial);
      rp.reprocessed_from = first;
      rp.archive_path = repo.show(origin).run.archive_path;
      w.add(rp, w.factory(3, 0, true), "REVIEW");
    }
  }
  // The imported land field run: AINS and legacy, its gyro z bias far off the factory's.
  NewRun field = w.next("st-A", "U-4");
  field.setting = calib::core::Setting::kLand;
  field.origin = "imported from /media/usb/U-4";
  RunCompletion land = w.factory(4, 0);
  land.calibrations[1] = seeded_calibration(14, Method::kLegacy, false);
  calib::core::ParamVector v = land.calibrations[0].params.to_vector();
  v(14) = kFieldGyroZDegPerHour * kPi / 180.0 / 3600.0;
  land.calibrations[0].params = calib::core::ParamSet::from_vector(v);
  w.add(field, land, "PASS");
  // The ends that are not the unit's, and one that is.
  w.add(w.next("st-A", "U-4"),
        w.ended(RunState::kAborted,
                "table: turntable tcp:127.0.0.1:1502: connection refused after 10 attempt(s)",
                RunVerdict::kStationFault),
        "STATION-FAULT");
  w.add(w.next("st-A", "U-5"), w.ended(RunState::kAborted, "unit loose in fixture"), "ABORTED");
  w.add(w.next("st-A", "U-6"),
        w.ended(RunState::kInterrupted, "the station daemon stopped while the run was running"),
        "INTERRUPTED");
  w.add(w.next("st-A", "U-7"), w.ended(RunState::kFailed, "data check: IMU stream stopped"),
        "FAILED");
  // NLSQ did not converge: its σ is huge, every difference "within" the bound.
  RunCompletion diverged = w.factory(6, 0);
  diverged.calibrations[1].converged = false;
  diverged.calibrations[1].sigma = calib::core::ParamSet::from_vector(
      diverged.calibrations[1].sigma.to_vector().cwiseAbs() * 1e6);
  w.add(w.next("st-A", "U-6"), diverged, "PASS");
  // The other station: one unit, on two days.
  w.add(w.next("st-B", "U-8"), w.factory(2, 1), "PASS");
  w.t += 86400000;  // the next day: a day of one run
  w.add(w.next("st-B", "U-8"), w.factory(2, 1), "PASS");
  return w.rows;
}

/// Whether the row stands for its capture: no run of its capture (the runs linked to it through
/// reprocessed_from, either way) has a higher id. Computed from the rows alone.
inline bool truth_stands(const TruthRow& row, const std::vector<TruthRow>& rows) {
  std::map<RunId, RunId> origin;
  for (const TruthRow& r : rows)
    if (r.reprocessed_from) origin[r.run_id] = *r.reprocessed_from;
  auto root = [&](RunId id) {
    while (origin.count(id)) id = origin[id];
    return id;
  };
  for (const TruthRow& r : rows)
    if (r.run_id > row.run_id && root(r.run_id) == root(row.run_id)) return false;
  return true;
}

/// The rows a fleet aggregate counts for `setting` ("" every setting) and `verdict` ("" every).
inline std::vector<TruthRow> truth_counted(const std::vector<TruthRow>& rows,
                                           const std::string& setting, const std::string& verdict) {
  std::vector<TruthRow> out;
  for (const TruthRow& r : rows)
    if (truth_stands(r, rows) && (setting.empty() || r.setting == setting) &&
        (verdict.empty() || r.verdict == verdict))
      out.push_back(r);
  return out;
}

}  // namespace imucal::db::test
