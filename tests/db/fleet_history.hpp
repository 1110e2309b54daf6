#pragma once
// A calibration history for the fleet questions (db/history/fleet_stats.hpp), written through the
// repository, with every row also returned to the test so that it can compute the expected
// answers on its own: three stations, six serials, five days of March 2024 (and one run before
// 1970 when asked), verdicts PASS, REVIEW, FAILED, STATION-FAULT, ABORTED and INTERRUPTED, two
// live runs (one with its AINS result
// already stored), and AINS parameters drawn around a per-station mean so that the stations'
// distributions differ. Used by tests/db/fleet_stats_test.cpp and tests/tools/stationweb_test.cpp.
#include <algorithm>
#include <cmath>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "db/history/fleet_stats.hpp"
#include "db/history/sqlite_repository.hpp"
#include "tests/db/history_fixtures.hpp"

namespace imucal::db::test {
using namespace imucal::db::history;

struct FleetRow {
  RunId run_id = 0;
  std::string station, serial;
  TimestampMs started_at_ms = 0;
  std::string verdict;  ///< "PASS", "REVIEW", "FAILED", "STATION-FAULT", "ABORTED",
                        ///< "INTERRUPTED", "" (live)
  std::optional<calib::core::ParamVector> ains;  ///< the AINS values stored, if any
  std::optional<calib::core::ParamVector> ains_sigma;
  std::vector<std::string> unobservable;  ///< parameters the AINS result does not determine
};

inline const std::vector<std::string>& fleet_stations() {
  static const std::vector<std::string> s = {"st-A", "st-B", "st-C"};
  return s;
}

inline TimestampMs fleet_t0() { return parse_time_utc("2024-03-01T00:00:00Z"); }

/// AINS values of a navigation-grade unit (biases ~50 µg and 0.01 deg/h, M and ς ~100 ppm/µrad):
/// each serial its own level, each station a small offset of its own, run-to-run scatter a few
/// percent, 1-σ about 1.5 %.
inline CalibrationRecord fleet_ains(std::mt19937& rng, int serial, std::size_t station) {
  CalibrationRecord c = seeded_calibration(static_cast<long>(station), Method::kAins);
  std::normal_distribution<double> n01(0.0, 1.0);
  calib::core::ParamVector v, s;
  for (int i = 0; i < calib::core::ParamSet::kSize; ++i) {
    const double scale = i < 3 ? 5e-4 : (i >= 12 && i < 15) ? 5e-8 : 1e-4;
    v(i) = scale * (1.0 + 0.15 * serial + 0.05 * static_cast<double>(station) + 0.03 * n01(rng));
    s(i) = scale * 0.015 * (1.0 + 0.1 * std::abs(n01(rng)));
  }
  c.params = calib::core::ParamSet::from_vector(v);
  c.sigma = calib::core::ParamSet::from_vector(s);
  return c;
}

/// Run i's completion by its kind; records what it stored in `row`.
inline RunCompletion fleet_completion(int i, TimestampMs end, std::mt19937& rng, FleetRow& row,
                                      std::size_t station) {
  RunCompletion c;
  c.ended_at_ms = end;
  if (i % 11 == 0) {  // ended before calibrating: whose the end was, in turn (issue #50)
    switch ((i / 11) % 4) {
      case 0:  // the unit's own
        c.state = RunState::kFailed;
        c.reason = "data check: IMU stream stopped";
        row.verdict = "FAILED";
        break;
      case 1:  // the table could not be reached: the station's
        c.state = RunState::kAborted;
        c.verdict = RunVerdict::kStationFault;
        c.reason = "table: turntable tcp:127.0.0.1:1502: cannot connect after 10 attempt(s)";
        row.verdict = "STATION-FAULT";
        break;
      case 2:  // an operator's abort
        c.state = RunState::kAborted;
        c.reason = "unit loose in fixture";
        row.verdict = "ABORTED";
        break;
      default:  // the daemon died mid-run
        c.state = RunState::kInterrupted;
        c.reason = "the station daemon stopped while the run was running";
        row.verdict = "INTERRUPTED";
    }
    return c;
  }
  c = i % 7 == 0 ? review_completion(i, end) : pass_completion(i, end);
  c.calibrations[0] = fleet_ains(rng, i % 6, station);
  if (i % 13 == 4) {  // a result that leaves ς undetermined: placeholders 0 ± 0, not compared
    row.unobservable = {"table_misalignment_rad[0]", "table_misalignment_rad[1]",
                        "table_misalignment_rad[2]"};
    calib::core::ParamVector v = c.calibrations[0].params.to_vector(),
                             s = c.calibrations[0].sigma.to_vector();
    v.tail<3>().setZero();
    s.tail<3>().setZero();
    c.calibrations[0].params = calib::core::ParamSet::from_vector(v);
    c.calibrations[0].sigma = calib::core::ParamSet::from_vector(s);
    c.calibrations[0].unobservable = row.unobservable;
    c.crosscheck->not_compared = row.unobservable;
  }
  row.verdict = i % 7 == 0 ? "REVIEW" : "PASS";
  row.ains = c.calibrations[0].params.to_vector();
  row.ains_sigma = c.calibrations[0].sigma.to_vector();
  return c;
}

/// Writes 60 finished runs and 2 live ones into `repo` (and, with `before_1970`, one more run
/// started 1969-12-31T23:59:59Z); returns them in the order written.
inline std::vector<FleetRow> write_fleet_history(SqliteRepository& repo, bool before_1970 = false) {
  std::mt19937 rng(2024);
  std::vector<FleetRow> rows;
  const TimestampMs day = 86400000, minute = 60000;
  for (int i = 0; i < 60; ++i) {
    FleetRow row;
    const std::size_t station = static_cast<std::size_t>((i / 2 + i % 5) % 3);
    row.station = fleet_stations()[station];
    row.serial = "SN-" + std::to_string(1 + i % 6);
    row.started_at_ms = fleet_t0() + (i % 5) * day + (i * 37 % 1380) * minute;
    NewRun run = new_run(row.serial, row.started_at_ms);
    run.station = row.station;
    row.run_id = repo.create_run(run);
    repo.finish_run(row.run_id,
                    fleet_completion(i, row.started_at_ms + 50 * minute, rng, row, station));
    rows.push_back(row);
  }
  for (int k = 0; k < 2; ++k) {  // live: one still running, one calibrating with AINS stored
    FleetRow row{0,
                 fleet_stations()[k],
                 "SN-" + std::to_string(1 + k),
                 fleet_t0() + 4 * day + (1400 + k) * minute,
                 "",
                 {},
                 {},
                 {}};
    NewRun run = new_run(row.serial, row.started_at_ms, RunState::kRunning);
    run.station = row.station;
    row.run_id = repo.create_run(run);
    if (k == 1) {
      const CalibrationRecord a = fleet_ains(rng, k, static_cast<std::size_t>(k));
      repo.store_calibration(row.run_id, a);
      row.ains = a.params.to_vector();
      row.ains_sigma = a.sigma.to_vector();
    }
    rows.push_back(row);
  }
  if (before_1970) {
    FleetRow row{0, "st-A", "SN-OLD", -1000, "", {}, {}, {}};
    NewRun run = new_run(row.serial, row.started_at_ms);
    run.station = row.station;
    row.run_id = repo.create_run(run);
    repo.finish_run(row.run_id, fleet_completion(11, 0, rng, row, 0));  // STATION-FAULT
    rows.push_back(row);
  }
  return rows;
}

/// The AINS value of parameter `param` the row contributes to a distribution, if any.
inline std::optional<double> fleet_value(const FleetRow& r, int param) {
  const std::string& name = calib::core::param_info(param).name;
  if (!r.ains ||
      std::find(r.unobservable.begin(), r.unobservable.end(), name) != r.unobservable.end())
    return std::nullopt;
  return (*r.ains)(param);
}

/// Whether the row belongs to the filter, by db/history/fleet_stats.hpp's definition.
inline bool fleet_row_matches(const FleetRow& r, const FleetFilter& f) {
  return (!f.since_ms || r.started_at_ms >= *f.since_ms) &&
         (!f.until_ms || r.started_at_ms < *f.until_ms) &&
         (!f.station || r.station == *f.station) && (!f.serial || r.serial == *f.serial);
}

/// The statistics of db/history/fleet_stats.hpp computed here, apart from the code under test: sums
/// in long double, quantiles by the rank formula on a sorted copy.
struct ExpectedSummary {
  std::int64_t n = 0;
  double mean = 0, sd = 0, min = 0, q1 = 0, median = 0, q3 = 0, max = 0;
};

inline ExpectedSummary expected_summary(std::vector<double> v) {
  ExpectedSummary e;
  e.n = static_cast<std::int64_t>(v.size());
  std::sort(v.begin(), v.end());
  long double sum = 0, sum_sq = 0;
  for (double x : v) sum += x;
  const long double mean = sum / v.size();
  for (double x : v) sum_sq += (x - mean) * (x - mean);
  e.mean = static_cast<double>(mean);
  e.sd = v.size() > 1 ? static_cast<double>(std::sqrt(sum_sq / (v.size() - 1))) : 0.0;
  auto q = [&](double p) {
    const double rank = p * static_cast<double>(v.size() - 1);
    const auto below = static_cast<std::size_t>(rank);
    const double frac = rank - static_cast<double>(below);
    return frac == 0.0 ? v[below] : v[below] * (1 - frac) + v[below + 1] * frac;
  };
  e.min = v.front();
  e.max = v.back();
  e.q1 = q(0.25);
  e.median = q(0.5);
  e.q3 = q(0.75);
  return e;
}

}  // namespace imucal::db::test
