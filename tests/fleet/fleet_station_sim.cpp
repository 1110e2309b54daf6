// fleet_station_sim: one simulated station for the fleet replication test (issue #24). It writes
// runs into its own SQLite history exactly as stationd's run controller does (create → running →
// calibrating → finish PASS / REVIEW / failed, a diagnosis kept afterwards, a reprocess now and
// then, a table run of two units), while the real outbox sender (station/daemon/fleet_sender.hpp)
// carries them to the fleet store. At the end it waits for its outbox to drain and prints its
// sender's status as JSON. Exit 0: drained; 1: not drained in --drain-timeout-s; 2: bad arguments.
//   fleet_station_sim --db FILE --url URL --password-file FILE --station-id ID
//                     [--runs 100] [--period-ms 700] [--seed 1] [--drain-timeout-s 240]
#include <chrono>
#include <cstdlib>
#include <iostream>
#include <string>
#include <thread>

#include "db/history/sqlite_repository.hpp"
#include "station/daemon/fleet_sender.hpp"
#include "tests/db/history_fixtures.hpp"

namespace {

using namespace imucal;

struct Options {
  std::string db, url, password_file, station_id;
  int runs = 100, period_ms = 700, drain_timeout_s = 240;
  long seed = 1;
};

Options parse(int argc, char** argv) {
  Options o;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string k = argv[i], v = argv[i + 1];
    if (k == "--db")
      o.db = v;
    else if (k == "--url")
      o.url = v;
    else if (k == "--password-file")
      o.password_file = v;
    else if (k == "--station-id")
      o.station_id = v;
    else if (k == "--runs")
      o.runs = std::stoi(v);
    else if (k == "--period-ms")
      o.period_ms = std::stoi(v);
    else if (k == "--seed")
      o.seed = std::stol(v);
    else if (k == "--drain-timeout-s")
      o.drain_timeout_s = std::stoi(v);
    else
      throw std::invalid_argument("unknown option " + k);
  }
  if (o.db.empty() || o.url.empty() || o.station_id.empty())
    throw std::invalid_argument("--db, --url and --station-id are required");
  return o;
}

/// Run i of the station, through its life cycle; every tenth a REVIEW, every tenth (offset) a
/// failure, a reprocess of the previous run, a two-unit table run.
void one_run(db::history::SqliteRepository& repo, const Options& o, int i, bool pair,
             db::history::RunId& previous) {
  const db::history::TimestampMs t = db::history::now_ms();
  db::history::NewRun n =
      db::test::new_run("SN-" + std::to_string(o.seed) + "-" + std::to_string(i % 37), t);
  n.station = o.station_id;
  if (i % 10 == 5 && previous > 0) n.reprocessed_from = previous;
  const db::history::RunId id = repo.create_run(n);
  db::history::RunId sibling = 0;
  if (pair) {
    db::history::NewRun s = n;
    s.serial = "SN-" + std::to_string(o.seed) + "-B" + std::to_string(i);
    s.slot = "B";
    s.table_run_id = id;
    sibling = repo.create_run(s);
  }
  repo.update_run_state(id, db::history::RunState::kRunning);
  repo.update_run_state(id, db::history::RunState::kCalibrating);
  const long seed = o.seed * 1000 + i;
  if (i % 10 == 7) {
    repo.update_run_state(id, db::history::RunState::kFailed, "capture: IMU stream lost at step 3");
  } else if (i % 10 == 3) {
    repo.finish_run(id, db::test::review_completion(seed, db::history::now_ms()));
  } else {
    repo.finish_run(id, db::test::pass_completion(seed, db::history::now_ms()));
    if (i % 4 == 0)
      repo.set_diagnosis(id, R"({"verdict":"consistent","run":)" + std::to_string(i) + "}");
  }
  if (sibling > 0)
    repo.finish_run(sibling, db::test::pass_completion(seed + 500, db::history::now_ms()));
  previous = id;
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  try {
    o = parse(argc, argv);
  } catch (const std::exception& e) {
    std::cerr << "fleet_station_sim: " << e.what() << "\n";
    return 2;
  }
  station::config::FleetConfig fleet;
  fleet.url = o.url;
  fleet.station_id = o.station_id;
  fleet.password_file = o.password_file;
  db::history::SqliteRepository repo(o.db);
  station::daemon::FleetSender sender(o.db, fleet);
  db::history::RunId previous = 0;
  for (int i = 0, made = 0; made < o.runs; ++i) {
    const bool pair = i % 10 == 8 && made + 2 <= o.runs;  // a two-unit table run
    one_run(repo, o, i, pair, previous);
    made += pair ? 2 : 1;
    std::this_thread::sleep_for(std::chrono::milliseconds(o.period_ms));
  }
  const bool drained = sender.wait_until_drained(std::chrono::seconds(o.drain_timeout_s));
  std::cout << sender.status().to_json().dump() << std::endl;
  return drained ? 0 : 1;
}
