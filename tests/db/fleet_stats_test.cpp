// db::history::SqliteFleetStats (db/history/fleet_stats.hpp) against answers the test computes
// itself from the rows it wrote (tests/db/fleet_history.hpp): runs per station and UTC day, verdict
// counts per station, a parameter's distribution per station (count, mean, sample std, min,
// quartiles, max), each with every filter (since, until, station, serial) alone and together; table
// runs; the values of a filter bound, never spliced (quotes and semicolons leave the database as it
// was); bad input.
#include "db/history/fleet_stats.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <map>
#include <tuple>

#include "db/history/sqlite_fleet_stats.hpp"
#include "tests/db/fleet_history.hpp"

namespace imucal::db {
using namespace imucal::db::history;
namespace {

using test::FleetRow;

constexpr TimestampMs kDayMs = 86400000;

class FleetStatsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    path_ = dir_.file("history.sqlite");
    SqliteRepository repo(path_);
    rows_ = test::write_fleet_history(repo, /*before_1970=*/true);
  }

  static bool matches(const FleetRow& r, const FleetFilter& f) {
    return test::fleet_row_matches(r, f);
  }

  /// The filters every check runs with: none, each alone, and all together.
  std::vector<FleetFilter> filters() const {
    const TimestampMs t0 = test::fleet_t0();
    std::vector<FleetFilter> out(6);
    out[1].since_ms = t0 + kDayMs + 3600000;  // mid-morning of day 2: splits a day
    out[2].until_ms = t0 + 3 * kDayMs;
    out[3].station = "st-B";
    out[4].serial = "SN-3";
    out[5] = {t0 + kDayMs, t0 + 4 * kDayMs + 7200000, std::string("st-C"), std::string("SN-2"), {},
              {}};
    return out;
  }

  test::TempDir dir_;
  std::string path_;
  std::vector<FleetRow> rows_;
};

std::string describe(const FleetFilter& f) {
  return "since " + (f.since_ms ? std::to_string(*f.since_ms) : "-") + " until " +
         (f.until_ms ? std::to_string(*f.until_ms) : "-") + " station " + f.station.value_or("-") +
         " serial " + f.serial.value_or("-");
}

TEST_F(FleetStatsTest, RunsPerStationAndDayCountEveryMatchingRunOnce) {
  SqliteFleetStats stats(path_);
  for (const FleetFilter& f : filters()) {
    std::map<std::pair<std::string, std::int64_t>, std::int64_t> expected;
    for (const FleetRow& r : rows_)
      if (matches(r, f))
        ++expected[{r.station, static_cast<std::int64_t>(
                                   std::floor(static_cast<double>(r.started_at_ms) / kDayMs))}];
    std::map<std::pair<std::string, std::int64_t>, std::int64_t> got;
    const auto counts = stats.runs_per_station_day(f);
    for (const auto& c : counts) got[{c.station, c.day}] = c.runs;
    EXPECT_EQ(got, expected) << describe(f);
    EXPECT_EQ(got.size(), counts.size()) << "a (station, day) pair twice: " << describe(f);
    EXPECT_TRUE(std::is_sorted(counts.begin(), counts.end(), [](const auto& a, const auto& b) {
      return std::tie(a.station, a.day) < std::tie(b.station, b.day);
    })) << describe(f);
  }
  // The run 1 s before the epoch lies on day -1, not day 0.
  FleetFilter old;
  old.serial = "SN-OLD";
  const auto c = stats.runs_per_station_day(old);
  ASSERT_EQ(c.size(), 1u);
  EXPECT_EQ(c[0].day, -1);
}

/// The counts of one station in a fixed order: pass, review, failed, station fault, aborted,
/// interrupted, live.
using VerdictSlots = std::array<std::int64_t, 7>;

std::size_t verdict_slot(const std::string& verdict) {
  const char* const order[] = {"PASS",          "REVIEW",  "FAILED",
                               "STATION-FAULT", "ABORTED", "INTERRUPTED"};
  for (std::size_t k = 0; k < 6; ++k)
    if (verdict == order[k]) return k;
  return 6;  // live
}

TEST_F(FleetStatsTest, VerdictCountsPerStationSplitEveryVerdictAndLive) {
  SqliteFleetStats stats(path_);
  for (const FleetFilter& f : filters()) {
    std::map<std::string, VerdictSlots> expected;
    for (const FleetRow& r : rows_)
      if (matches(r, f)) ++expected[r.station][verdict_slot(r.verdict)];
    std::map<std::string, VerdictSlots> got;
    for (const auto& v : stats.verdict_counts_per_station(f)) {
      EXPECT_EQ(v.total(), v.pass + v.review + v.failed + v.station_fault + v.aborted +
                               v.interrupted + v.live);
      got[v.station] = {v.pass,    v.review,      v.failed, v.station_fault,
                        v.aborted, v.interrupted, v.live};
    }
    EXPECT_EQ(got, expected) << describe(f);
  }
  // The data hold every kind, so a mix-up between them would show.
  VerdictSlots sum{};
  for (const auto& v : stats.verdict_counts_per_station({})) {
    const VerdictSlots one = {v.pass,    v.review,      v.failed, v.station_fault,
                              v.aborted, v.interrupted, v.live};
    for (std::size_t k = 0; k < sum.size(); ++k) sum[k] += one[k];
  }
  for (std::size_t k = 0; k < 6; ++k) EXPECT_GT(sum[k], 0) << "verdict slot " << k;
  EXPECT_EQ(sum[6], 2) << "two live runs";
}

// Issue #50: a station's faults, an operator's abort and an interrupted run are not the unit's:
// the share a unit's yield is taken of holds PASS, REVIEW and FAILED alone, and the station's
// faults are counted per station. Counted here from the rows the test wrote.
TEST_F(FleetStatsTest, AUnitsYieldCountsOnlyItsOwnOutcomesAndFaultsArePerStation) {
  SqliteFleetStats stats(path_);
  std::map<std::string, std::int64_t> own, faults;
  for (const FleetRow& r : rows_) {
    if (r.verdict == "PASS" || r.verdict == "REVIEW" || r.verdict == "FAILED") ++own[r.station];
    if (r.verdict == "STATION-FAULT") ++faults[r.station];
  }
  std::int64_t all_faults = 0;
  for (const auto& v : stats.verdict_counts_per_station({})) {
    EXPECT_EQ(v.unit_outcomes(), own[v.station]) << v.station;
    EXPECT_EQ(v.station_fault, faults[v.station]) << v.station;
    all_faults += v.station_fault;
  }
  EXPECT_EQ(all_faults, 3) << "runs 11 and 55 and the run before 1970 could not reach the table";
}

TEST_F(FleetStatsTest, ParamDistributionEqualsStatisticsOfTheStoredAinsValues) {
  SqliteFleetStats stats(path_);
  for (int param : {0, 4, 14, 20, 25}) {  // 25: ς y, undetermined by some results
    for (const FleetFilter& f : filters()) {
      std::map<std::string, std::vector<double>> values;
      for (const FleetRow& r : rows_)
        if (const auto v = test::fleet_value(r, param); v && matches(r, f))
          values[r.station].push_back(*v);
      const auto got = stats.param_distribution(param, f);
      ASSERT_EQ(got.size(), values.size()) << describe(f);
      for (const ParamSummary& s : got) {
        SCOPED_TRACE(calib::core::param_info(param).name + " " + s.station + " " + describe(f));
        ASSERT_TRUE(values.count(s.station));
        const test::ExpectedSummary e = test::expected_summary(values[s.station]);
        const double tol = 1e-12 * std::max(std::abs(e.max), std::abs(e.min));
        EXPECT_EQ(s.count, e.n);
        EXPECT_NEAR(s.mean, e.mean, tol);
        EXPECT_NEAR(s.std_dev, e.sd, tol);
        EXPECT_EQ(s.min, e.min);
        EXPECT_EQ(s.max, e.max);
        EXPECT_NEAR(s.q1, e.q1, tol);
        EXPECT_NEAR(s.median, e.median, tol);
        EXPECT_NEAR(s.q3, e.q3, tol);
      }
    }
  }
}

TEST_F(FleetStatsTest, AResultThatDoesNotDetermineTheParameterIsLeftOut) {
  SqliteFleetStats stats(path_);
  std::int64_t with_varsigma = 0, all = 0;
  for (const FleetRow& r : rows_) {
    all += r.ains ? 1 : 0;
    with_varsigma += test::fleet_value(r, 26) ? 1 : 0;
  }
  ASSERT_LT(with_varsigma, all);  // the data hold such results
  std::int64_t counted = 0;
  for (const ParamSummary& s : stats.param_distribution(26, {})) {
    counted += s.count;
    EXPECT_NE(s.min, 0.0) << s.station << ": a placeholder 0 was counted";
  }
  EXPECT_EQ(counted, with_varsigma);
  std::int64_t counted_bias = 0;
  for (const ParamSummary& s : stats.param_distribution(0, {})) counted_bias += s.count;
  EXPECT_EQ(counted_bias, all);
}

TEST_F(FleetStatsTest, ARunStillLiveCountsInTheDistributionWithItsStoredAinsResult) {
  SqliteFleetStats stats(path_);
  const FleetRow& live = rows_[61];
  ASSERT_TRUE(live.verdict.empty() && live.ains);
  FleetFilter only;
  only.since_ms = live.started_at_ms;
  only.until_ms = live.started_at_ms + 1;
  const auto d = stats.param_distribution(14, only);
  ASSERT_EQ(d.size(), 1u);
  EXPECT_EQ(d[0].count, 1);
  EXPECT_EQ(d[0].median, (*live.ains)(14));
  EXPECT_EQ(d[0].std_dev, 0.0);
}

TEST_F(FleetStatsTest, AinsResultsAreTheFullyDeterminedFactoryResultsAsStored) {
  {  // a field run and a reprocessing with AINS results: neither is a station's table result
    SqliteRepository repo(path_);
    NewRun land = test::new_run("SN-1", test::fleet_t0() + 3600000);
    land.station = "st-A";
    land.setting = calib::core::Setting::kLand;
    const RunId l = repo.create_run(land);
    RunCompletion land_done = test::pass_completion(3, test::fleet_t0() + 7200000);
    // Its AINS result as a table run's (every term determined): only its setting leaves it out.
    land_done.calibrations = {test::seeded_calibration(3, Method::kAins),
                              test::seeded_calibration(3, Method::kLegacy, false)};
    repo.finish_run(l, land_done);
    NewRun again = test::new_run("SN-2", test::fleet_t0() + 3600000);
    again.station = "st-A";
    again.reprocessed_from = rows_[1].run_id;
    const RunId a = repo.create_run(again);
    repo.finish_run(a, test::pass_completion(4, test::fleet_t0() + 7200000));
  }
  SqliteFleetStats stats(path_);
  int undetermined = 0;
  for (const FleetFilter& f : filters()) {
    std::vector<const FleetRow*> expected;
    for (const FleetRow& r : rows_) {
      if (!r.ains || !matches(r, f)) continue;
      if (!r.unobservable.empty()) {
        ++undetermined;
        continue;
      }
      expected.push_back(&r);
    }
    const std::vector<AinsResultRow> got = stats.ains_results(f);
    ASSERT_EQ(got.size(), expected.size()) << describe(f);
    for (std::size_t i = 0; i < got.size(); ++i) {
      SCOPED_TRACE("run " + std::to_string(got[i].run_id) + " " + describe(f));
      EXPECT_EQ(got[i].run_id, expected[i]->run_id);
      EXPECT_EQ(got[i].local_run_id, expected[i]->run_id);
      EXPECT_EQ(got[i].station, expected[i]->station);
      EXPECT_EQ(got[i].serial, expected[i]->serial);
      EXPECT_EQ(got[i].started_at_ms, expected[i]->started_at_ms);
      EXPECT_EQ(got[i].value.to_vector(), *expected[i]->ains) << "the numbers exactly as stored";
      EXPECT_EQ(got[i].sigma.to_vector(), *expected[i]->ains_sigma);
    }
  }
  EXPECT_GT(undetermined, 0) << "the data hold results that are left out";
}

TEST_F(FleetStatsTest, FilterValuesAreBoundNeverSpliced) {
  const std::string evil = "x'; DROP TABLE runs; --";
  std::size_t runs_before = 0;
  {
    SqliteRepository repo(path_, {true, false, 5000});
    runs_before = repo.total_run_count();
  }
  SqliteFleetStats stats(path_);
  FleetFilter f;
  f.station = evil;
  EXPECT_TRUE(stats.runs_per_station_day(f).empty());
  EXPECT_TRUE(stats.verdict_counts_per_station(f).empty());
  EXPECT_TRUE(stats.param_distribution(3, f).empty());
  f.station = "st-A' OR '1'='1";
  EXPECT_TRUE(stats.verdict_counts_per_station(f).empty());
  FleetFilter s;
  s.serial = evil;  // not a serial: refused before any SQL
  EXPECT_THROW(stats.verdict_counts_per_station(s), InvalidInput);
  SqliteRepository repo(path_, {true, false, 5000});
  EXPECT_EQ(repo.total_run_count(), runs_before);
  EXPECT_EQ(repo.integrity_check(), "ok");
}

TEST_F(FleetStatsTest, TableRunMembersAreTheFirstUnitAndEveryRunNamingIt) {
  std::vector<RunId> ids;
  {
    SqliteRepository repo(path_);
    NewRun first = test::new_run("SN-T1", test::fleet_t0());
    first.slot = "A";
    ids.push_back(repo.create_run(first));
    for (const char* sn : {"SN-T2", "SN-T3"}) {
      NewRun sib = test::new_run(sn, test::fleet_t0());
      sib.slot = std::string("B") + sn[4];
      sib.table_run_id = ids.front();
      ids.push_back(repo.create_run(sib));
    }
  }
  SqliteFleetStats stats(path_);
  EXPECT_EQ(stats.table_run_members(ids.front()), ids);
  EXPECT_EQ(stats.table_run_members(rows_[0].run_id), std::vector<RunId>{rows_[0].run_id});
  EXPECT_TRUE(stats.table_run_members(999999).empty());
}

TEST_F(FleetStatsTest, BadInputIsRefusedNamingWhatIsWrong) {
  SqliteFleetStats stats(path_);
  EXPECT_THROW(stats.param_distribution(27, {}), InvalidInput);
  EXPECT_THROW(stats.param_distribution(-1, {}), InvalidInput);
  FleetFilter backwards;
  backwards.since_ms = 2000;
  backwards.until_ms = 1000;
  const std::string m =
      test::expect_throw_message<InvalidInput>([&] { stats.runs_per_station_day(backwards); });
  EXPECT_NE(m.find("since"), std::string::npos) << m;
  EXPECT_EQ(param_index("gyro_bias_radps[2]"), 14);
  EXPECT_EQ(param_index("accel_M[0][1]"), 4);
  const std::string p = test::expect_throw_message<InvalidInput>([] { param_index("gyro_bias"); });
  EXPECT_NE(p.find("gyro_bias"), std::string::npos) << p;
  EXPECT_THROW(SqliteFleetStats(dir_.file("missing.sqlite")), NotFound);
  std::FILE* junk = std::fopen(dir_.file("junk.sqlite").c_str(), "w");
  std::fputs("not a database, just text that is long enough to be a header....", junk);
  std::fclose(junk);
  EXPECT_THROW(SqliteFleetStats(dir_.file("junk.sqlite")), DbError);
}

TEST(FleetStatsHelpers, SummarizeAndUtcDayFollowTheirDefinitions) {
  std::vector<double> v = {4, 1, 3, 2};
  const ParamSummary s = summarize(v);
  EXPECT_EQ(s.count, 4);
  EXPECT_DOUBLE_EQ(s.mean, 2.5);
  EXPECT_DOUBLE_EQ(s.std_dev, std::sqrt(5.0 / 3.0));
  EXPECT_DOUBLE_EQ(s.q1, 1.75);
  EXPECT_DOUBLE_EQ(s.median, 2.5);
  EXPECT_DOUBLE_EQ(s.q3, 3.25);
  EXPECT_EQ(s.min, 1);
  EXPECT_EQ(s.max, 4);
  std::vector<double> one = {7};
  const ParamSummary o = summarize(one);
  EXPECT_EQ(o.std_dev, 0.0);
  EXPECT_EQ(o.q1, 7);
  EXPECT_EQ(o.q3, 7);
  std::vector<double> none;
  EXPECT_EQ(summarize(none).count, 0);
  EXPECT_EQ(utc_day(0), 0);
  EXPECT_EQ(utc_day(kDayMs - 1), 0);
  EXPECT_EQ(utc_day(kDayMs), 1);
  EXPECT_EQ(utc_day(-1), -1);
  EXPECT_EQ(utc_day(-kDayMs), -1);
  EXPECT_EQ(utc_day(-kDayMs - 1), -2);
}

}  // namespace
}  // namespace imucal::db
