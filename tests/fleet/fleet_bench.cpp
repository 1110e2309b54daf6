// fleet_bench: the fleet store's query speed at factory scale (issue #24, "what it must show" 2).
// Starts a throw-away PostgreSQL cluster (tests/support/pg_cluster.hpp), fills it with N runs
// (default 10^6: 20 stations, 200 003 serials, one year, one AINS calibration each with jsonb
// parameter sets), ANALYZEs, then times through the product's own code:
//   * history of one serial across stations (FleetRepository::history), 200 random serials;
//   * a week's parameter distribution by station (PgFleetStats::param_distribution, the fleet
//     page's query), 50 random weeks;
// and prints the median and the maximum, with the plans (EXPLAIN ANALYZE) showing the indexes.
//   fleet_bench [--runs N]
#include <algorithm>
#include <chrono>
#include <iostream>
#include <random>
#include <string>

#include "calib/core/param_set.hpp"
#include "db/fleet/fleet_repository.hpp"
#include "db/fleet/fleet_schema.hpp"
#include "db/fleet/pg_fleet_stats.hpp"
#include "tests/support/pg_cluster.hpp"

namespace {

using namespace imucal;
using Clock = std::chrono::steady_clock;
constexpr long long kT0 = 1735689600000LL;  // 2025-01-01T00:00:00Z
constexpr long long kYearMs = 365LL * 86400000LL;
constexpr long long kWeekMs = 7LL * 86400000LL;
constexpr int kStations = 20;
constexpr long long kSerials = 200003;  // prime to the station count: a unit visits stations

/// A jsonb array of `n` random values of scale `s` (SQL text, no input values in it).
std::string rand_array(int n, const char* s) {
  std::string a = "jsonb_build_array(";
  for (int i = 0; i < n; ++i) a += std::string(i ? "," : "") + "(random() - 0.5) * " + s;
  return a + ")";
}
std::string rand_matrix(const char* s) {
  return "jsonb_build_array(" + rand_array(3, s) + "," + rand_array(3, s) + "," + rand_array(3, s) +
         ")";
}
std::string rand_params(const char* scale) {
  return "jsonb_build_object('accel_bias_mps2', " + rand_array(3, scale) + ", 'accel_M', " +
         rand_matrix(scale) + ", 'gyro_bias_radps', " + rand_array(3, scale) + ", 'gyro_M', " +
         rand_matrix(scale) + ", 'table_misalignment_rad', " + rand_array(3, scale) + ")";
}

/// The 27 parameters' jsonb paths in calib::core::param_info order, as an SQL array of path texts:
/// "accel_M[0][1]" → '{accel_M,0,1}'.
std::string param_paths() {
  std::string out = "ARRAY[";
  for (int i = 0; i < calib::core::ParamSet::kSize; ++i) {
    const std::string name = calib::core::param_info(i).name;
    std::string path = "{" + name.substr(0, name.find('['));
    for (std::size_t at = name.find('['); at != std::string::npos; at = name.find('[', at + 1))
      path += "," + name.substr(at + 1, name.find(']', at) - at - 1);
    out += std::string(i ? "," : "") + "'" + path + "}'";
  }
  return out + "]";
}

void fill(const test_support::PgCluster& pg, long long n) {
  const std::string step = std::to_string(kYearMs / n);
  pg.admin(
      "INSERT INTO runs (station_id, run_uuid, local_run_id, revision, serial, operator, "
      "station, sequence_name, sequence_sha256, software_version, started_at_ms, ended_at_ms, "
      "state, failure_reason, reasons, archive_path, archive_sha256, slot, capture_json, "
      "diagnosis_json, setting, origin, promoted_by, promote_reason) "
      "SELECT 'ST-' || lpad((g % " +
          std::to_string(kStations) +
          ")::text, 2, '0'), md5(g::text), g, 7, "
          "'SN-' || lpad((g % " +
          std::to_string(kSerials) +
          ")::text, 6, '0'), 'op', "
          "'ST-' || lpad((g % " +
          std::to_string(kStations) +
          ")::text, 2, '0'), 'factory-std', '', "
          "'bench', " +
          std::to_string(kT0) + " + g::bigint * " + step + ", " + std::to_string(kT0) +
          " + g::bigint * " + step +
          " + 3600000, CASE WHEN g % 50 = 0 THEN 'review' WHEN g % 97 = 0 "
          "THEN 'failed' ELSE 'done' END, '', '[]', '/data/runs/' || g, '', '', '', '', "
          "'factory', '', '', '' FROM generate_series(1, " +
          std::to_string(n) + ") g",
      "fleet");
  pg.admin(
      "INSERT INTO calibrations (run_id, method, params, sigma, converged, iterations, "
      "runtime_s, warnings, metrics, body_frame, unobservable, notes) SELECT id, 'ains', " +
          rand_params("1e-4") + ", " + rand_params("1e-6") +
          ", true, 12, 40.0, '[]', NULL, "
          "'housing', '[]', '[]' FROM runs WHERE state <> 'failed'",
      "fleet");
  // The writer's derived column (fleet_writer.cpp ains_values), as it would have stored it.
  pg.admin(
      "UPDATE runs r SET ains_values = ARRAY(SELECT (c.params #>> p.path::text[])::float8 FROM "
      "unnest(" +
          param_paths() +
          "::text[]) WITH ORDINALITY p(path, i) ORDER BY p.i) "
          "FROM calibrations c WHERE c.run_id = r.id AND c.method = 'ains'",
      "fleet");
  // Runs arrive at a store in time order, so its rows lie in time order; the UPDATE above scattered
  // them, and CLUSTER puts them back where a real store's would be.
  pg.admin("CLUSTER runs USING runs_by_time", "fleet");
  pg.admin("VACUUM ANALYZE", "fleet");
}

template <typename F>
void time_it(const char* what, int n, F f) {
  std::vector<double> ms;
  for (int i = 0; i < n; ++i) {
    const auto t0 = Clock::now();
    f(i);
    ms.push_back(std::chrono::duration<double, std::milli>(Clock::now() - t0).count());
  }
  std::sort(ms.begin(), ms.end());
  std::cout << what << ": median " << ms[ms.size() / 2] << " ms, max " << ms.back() << " ms over "
            << n << "\n";
}

}  // namespace

int bench(int argc, char** argv);

/// Every error is caught, so the cluster's destructor stops the server (std::terminate would not).
int main(int argc, char** argv) {
  try {
    return bench(argc, argv);
  } catch (const std::exception& e) {
    std::cerr << "fleet_bench: " << e.what() << "\n";
    return 1;
  }
}

int bench(int argc, char** argv) {
  long long n = 1000000;
  for (int i = 1; i + 1 < argc; i += 2)
    if (std::string(argv[i]) == "--runs") n = std::stoll(argv[i + 1]);
  test_support::PgCluster pg;
  const auto target = db::fleet::parse_fleet_target(pg.url("fleet_writer"),
                                                    test_support::PgCluster::kWriterPassword);
  {
    db::fleet::PgConnection c(target);
    db::fleet::migrate_fleet(c);
  }
  const auto t_fill = Clock::now();
  fill(pg, n);
  std::cout << "filled " << n << " runs in "
            << std::chrono::duration<double>(Clock::now() - t_fill).count() << " s; size "
            << pg.admin("SELECT pg_size_pretty(pg_database_size('fleet'))", "fleet");
  const auto reader = db::fleet::parse_fleet_target(pg.url("fleet_reader"),
                                                    test_support::PgCluster::kReaderPassword);
  db::fleet::FleetRepository repo(reader);
  db::fleet::PgFleetStats stats(reader);
  std::mt19937_64 rng(7);
  std::vector<std::string> serials;
  for (int i = 0; i < 200; ++i) {
    char buf[16];
    const long long g = 1 + static_cast<long long>(rng() % static_cast<unsigned long long>(n));
    std::snprintf(buf, sizeof buf, "SN-%06lld", g % kSerials);
    serials.push_back(buf);
  }
  std::size_t seen = 0;
  time_it("history of one serial across stations", 200,
          [&](int i) { seen += repo.history(serials[static_cast<std::size_t>(i)]).size(); });
  std::cout << "  (" << seen / 200.0 << " runs per serial on average)\n";
  const int gyro_bias_z = db::history::param_index("gyro_bias_radps[2]");
  std::size_t per_week = 0;
  time_it("a week's gyro bias z distribution by station", 50, [&](int) {
    db::history::FleetFilter f;
    f.since_ms =
        kT0 + static_cast<long long>(rng() % static_cast<unsigned long long>(kYearMs - kWeekMs));
    f.until_ms = *f.since_ms + kWeekMs;
    for (const auto& s : stats.param_distribution(gyro_bias_z, f))
      per_week += static_cast<std::size_t>(s.count);
  });
  std::cout << "  (" << per_week / 50.0 << " calibrations per week)\n";
  std::cout << "\nplan, history:\n"
            << pg.admin(
                   "EXPLAIN ANALYZE SELECT * FROM runs r LEFT JOIN crosschecks x ON x.run_id = "
                   "r.id WHERE r.serial = '" +
                       serials[0] + "' ORDER BY r.started_at_ms DESC, r.id DESC",
                   "fleet");
  std::cout << "\nplan, a week's distribution:\n"
            << pg.admin("PREPARE week(int, text, bigint, bigint, text, text, text, text, bigint[]) AS " +
                            db::fleet::PgFleetStats::param_distribution_sql() +
                            "; EXPLAIN ANALYZE EXECUTE week(" + std::to_string(gyro_bias_z + 1) +
                            ", NULL, " + std::to_string(kT0 + 20 * kWeekMs) + ", " +
                            std::to_string(kT0 + 21 * kWeekMs) + ", NULL, NULL, NULL, NULL, '{}')",
                        "fleet");
  return 0;
}
