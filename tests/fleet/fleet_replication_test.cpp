// Issue #24, "what it must show" 1: twenty simulated stations (processes, tests/fleet/
// fleet_station_sim.cpp, each with the real outbox sender) store 100 runs each into one PostgreSQL
// concurrently, while the server is killed with SIGKILL and restarted three times and one station's
// connection is cut for a minute (every connection reset and the port refusing, through a
// forwarder: tests/support/tcp_proxy.hpp). At the end: 2 000 rows in the fleet store, each equal
// field by field to its station's SQLite, none twice, every outbox empty.
//
// That is the whole count (IMUCAL_WHOLE_COUNTS=1, ~110 s). ctest runs it at half its time scale:
// 50 runs a station at the same period, the three kills at half the delays (still while every
// station is producing) and a 30 s cut (six of the sender's 5 s maximum back-offs): 1 000 rows,
// every check the same. What the whole count adds is the minute-long cut and twice the rows; what
// the CI count keeps is every kind of loss (kills during writes, a cut, a kill during the cut).
#include <gtest/gtest.h>
#include <spawn.h>
#include <sys/wait.h>

#include <chrono>
#include <fstream>
#include <map>
#include <set>
#include <thread>

#include "db/fleet/fleet_repository.hpp"
#include "db/history/sqlite_repository.hpp"
#include "tests/support/ci_count.hpp"
#include "tests/support/fleet_compare.hpp"
#include "tests/support/pg_cluster.hpp"
#include "tests/support/tcp_proxy.hpp"

extern char** environ;

namespace imucal::db::fleet {
using namespace imucal::db::history;
namespace {

using namespace std::chrono_literals;
using test_support::PgCluster;

constexpr int kStations = 20;
constexpr int kRunsPerStationWhole = 100;

pid_t spawn(const std::vector<std::string>& argv, const std::string& out_file) {
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addopen(&fa, 1, out_file.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_adddup2(&fa, 1, 2);
  std::vector<char*> args;
  for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  pid_t pid = -1;
  const int rc = posix_spawn(&pid, args[0], &fa, nullptr, args.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  return rc == 0 ? pid : -1;
}

std::string slurp(const std::string& path) {
  std::ifstream in(path);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

/// Each of the station's runs equal, field by field, to its copy in the fleet store; returns the
/// number compared.
std::size_t compare_station(const FleetRepository& fleet, const std::string& db_path,
                            const std::string& station_id) {
  SqliteOptions ro;
  ro.read_only = true;
  const SqliteRepository local(db_path, ro);
  EXPECT_EQ(local.outbox_length(), 0u) << station_id << ": outbox not empty";
  std::vector<RunId> ids;
  for (const RunRecord& r : local.recent_runs(0)) ids.push_back(r.run_id);
  const std::vector<RunDetails> mine = local.details_of(ids);
  std::map<RunId, std::string> local_uuid, fleet_uuid;
  for (const RunDetails& d : mine) local_uuid[d.run.run_id] = d.run.uuid;
  std::map<std::string, RunDetails> stored;
  for (const RunRecord& r : fleet.station_runs(station_id, std::nullopt, 0)) {
    EXPECT_FALSE(stored.count(r.uuid)) << station_id << ": run " << r.uuid << " twice";
    stored[r.uuid] = fleet.show(r.run_id);
    fleet_uuid[r.run_id] = r.uuid;
  }
  EXPECT_EQ(stored.size(), mine.size()) << station_id;
  std::size_t equal = 0;
  for (const RunDetails& d : mine) {
    const auto it = stored.find(d.run.uuid);
    if (it == stored.end()) {
      ADD_FAILURE() << station_id << ": run " << d.run.run_id << " missing from the fleet store";
      continue;
    }
    const auto a = test_support::comparable_run(d, local_uuid);
    const auto b = test_support::comparable_run(it->second, fleet_uuid);
    EXPECT_EQ(a, b) << station_id << " run " << d.run.run_id;
    equal += a == b;
  }
  return equal;
}

TEST(FleetReplication, TwentyStationsLoseNothingThroughKillsAndACut) {
  // The time scale: 1 at the whole count, 1/2 in CI (runs, delays and the cut's length).
  const int scale_pct = test_support::whole_counts() ? 100 : 50;
  const int runs_per_station = kRunsPerStationWhole * scale_pct / 100;
  const auto scaled = [&](std::chrono::milliseconds t) { return t * scale_pct / 100; };
  PgCluster pg;
  test_support::ScopedTempDir dir("imucal_fleet_repl");
  const std::string password_file = dir.sub("password");
  std::ofstream(password_file) << PgCluster::kWriterPassword << "\n";
  test_support::TcpProxy proxy(pg.port());
  const std::string cut_url =
      "postgresql://fleet_writer@127.0.0.1:" + std::to_string(proxy.port()) + "/fleet";

  std::vector<pid_t> pids;
  for (int s = 0; s < kStations; ++s) {
    const std::string id = "ST-" + std::to_string(s);
    pids.push_back(
        spawn({IMUCAL_BIN_DIR "/fleet_station_sim", "--db", dir.sub(id + ".sqlite"), "--url",
               s == 0 ? cut_url : pg.url("fleet_writer"), "--password-file", password_file,
               "--station-id", id, "--runs", std::to_string(runs_per_station), "--period-ms", "700",
               "--seed", std::to_string(s + 1), "--drain-timeout-s", "240"},
              dir.sub(id + ".out")));
    ASSERT_GT(pids.back(), 0);
  }
  auto kill_and_restart = [&](std::chrono::milliseconds down) {
    pg.kill9();
    std::this_thread::sleep_for(down);
    pg.start();
  };
  // The schedule of the kills and the cut: fixed times (what they hit is the point), not
  // conditions.
  std::this_thread::sleep_for(scaled(8s));
  kill_and_restart(scaled(2s));  // 1
  std::this_thread::sleep_for(scaled(10s));
  kill_and_restart(scaled(3s));  // 2
  std::this_thread::sleep_for(scaled(4s));
  const auto cut_at = std::chrono::steady_clock::now();
  proxy.cut();  // station 0 loses its server for a minute (half a minute in CI)
  std::this_thread::sleep_for(scaled(12s));
  kill_and_restart(scaled(2s));  // 3, while station 0 is cut off
  std::this_thread::sleep_until(cut_at + scaled(61s));
  proxy.restore();

  int stations_that_saw_a_kill = 0;
  for (int s = 0; s < kStations; ++s) {
    int status = 0;
    ASSERT_EQ(waitpid(pids[static_cast<std::size_t>(s)], &status, 0),
              pids[static_cast<std::size_t>(s)]);
    const std::string out = slurp(dir.sub("ST-" + std::to_string(s) + ".out"));
    EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "ST-" << s << ": " << out;
    const auto st = nlohmann::json::parse(out.substr(out.rfind('{')), nullptr, false);
    ASSERT_TRUE(st.is_object()) << out;
    if (s == 0) {
      EXPECT_TRUE(st["last_error"].is_string()) << "station 0 saw its cut: " << out;
    }
    if (s > 0 && st["last_error"].is_string()) ++stations_that_saw_a_kill;
  }
  // The kills must have hit senders at work, or the test would prove nothing about them.
  EXPECT_GE(stations_that_saw_a_kill, kStations / 2);

  FleetRepository fleet(parse_fleet_target(pg.url("fleet_reader"), PgCluster::kReaderPassword));
  const std::size_t total = static_cast<std::size_t>(kStations * runs_per_station);
  EXPECT_EQ(fleet.total_run_count(), total);
  std::size_t equal = 0;
  for (int s = 0; s < kStations; ++s) {
    const std::string id = "ST-" + std::to_string(s);
    equal += compare_station(fleet, dir.sub(id + ".sqlite"), id);
  }
  EXPECT_EQ(equal, total);
  const std::string distinct = pg.admin(
      "SELECT count(*) || ' ' || count(DISTINCT (station_id, run_uuid)) FROM runs", "fleet");
  EXPECT_EQ(distinct, std::to_string(total) + " " + std::to_string(total) + "\n");
  std::cout << "fleet replication: " << equal << " runs equal field by field; "
            << stations_that_saw_a_kill << " of " << kStations - 1
            << " uncut stations saw a server kill\n";
}

}  // namespace
}  // namespace imucal::db::fleet
