#include "tools/stationctl/fleet_cmd.hpp"

#include <unistd.h>

#include <algorithm>
#include <iostream>
#include <vector>

#include "db/fleet/fleet_schema.hpp"
#include "db/fleet/fleet_writer.hpp"
#include "db/history/sqlite_repository.hpp"
#include "station/daemon/fleet_sender.hpp"

namespace imucal::tools::stationctl {

namespace {

/// The station's id in the store: --station-id, else the config's [fleet] station_id.
std::string resync_station_id(const Target& t, const std::string& station_id_option) {
  if (t.db.empty()) throw Failure{kBadInput, "fleet resync: no database (give --config or --db)"};
  if (t.fleet_url.empty() && !t.fleet_config)
    throw Failure{kBadInput,
                  "fleet resync: the config names no [fleet] store (or give --fleet URL)"};
  if (!station_id_option.empty()) return station_id_option;
  if (t.fleet_config) return t.fleet_config->station_id;
  throw Failure{kBadInput, "fleet resync: give --station-id"};
}

/// This database's runs: their ids ascending, their UUIDs.
struct LocalRuns {
  std::vector<db::history::RunId> ids;
  std::vector<std::string> uuids;
};

LocalRuns local_runs(const db::history::SqliteRepository& local) {
  LocalRuns runs;
  for (const db::history::RunRecord& r : local.recent_runs(0)) {
    runs.ids.push_back(r.run_id);
    runs.uuids.push_back(r.uuid);
  }
  std::sort(runs.ids.begin(), runs.ids.end());
  return runs;
}

/// Every run of `ids` stored in the fleet store, in chunks, with a count on a TTY.
db::fleet::UpsertCount store_runs(db::fleet::PgConnection& conn, const std::string& station_id,
                                  const db::history::SqliteRepository& local,
                                  const std::vector<db::history::RunId>& ids, bool as_json) {
  db::fleet::UpsertCount n;
  constexpr std::size_t kChunk = 500;
  for (std::size_t i = 0; i < ids.size(); i += kChunk) {
    const std::vector<db::history::RunId> chunk(ids.begin() + i,
                                                ids.begin() + std::min(ids.size(), i + kChunk));
    const auto runs = local.details_of(chunk);
    const auto c = db::fleet::upsert_runs(conn, station_id, runs);
    n.written += c.written;
    n.unchanged += c.unchanged;
    if (!as_json && isatty(STDERR_FILENO))
      std::cerr << "\rresync " << std::min(ids.size(), i + kChunk) << "/" << ids.size() << " runs"
                << std::flush;
  }
  if (!as_json && isatty(STDERR_FILENO)) std::cerr << "\n";
  return n;
}

/// What the resync did, as JSON or as text.
void print_resync(const json& r, bool as_json) {
  if (as_json) {
    print_json(r);
    return;
  }
  std::cout << "fleet store " << text(r, "fleet") << ": station " << text(r, "station_id")
            << " resynced: " << text(r, "runs") << " runs (" << text(r, "written") << " written, "
            << text(r, "unchanged") << " already there)\n";
  if (r.at("set_apart").get<std::size_t>() > 0)
    std::cout << text(r, "set_apart") << " runs the store held and this database does not (a "
              << "replaced or restored database) were set apart, kept, as station "
              << text(r, "set_apart_as") << "\n";
}

}  // namespace

CLI::App* add_fleet_commands(CLI::App& app, FleetArgs& a) {
  auto* fleet = app.add_subcommand("fleet", "this station's share of the factory's fleet store");
  fleet->require_subcommand(1);
  fleet->fallthrough();
  CLI::App* resync = fleet->add_subcommand(
      "resync",
      "rebuild this station's share of the fleet store from its SQLite history (the config's "
      "[fleet], or --fleet URL with --station-id): every run stored; runs the store holds and "
      "this database does not (a replaced or restored database) are kept, set apart as station "
      "ID.previous-TIME, never deleted; safe while stationd runs");
  resync->add_option("--station-id", a.station_id,
                     "the station's id in the store (default: the config's)");
  resync->fallthrough();
  return resync;
}

int cmd_fleet_resync(const Target& t, const FleetArgs& a, bool as_json) {
  const std::string station_id = resync_station_id(t, a.station_id);
  try {
    const db::fleet::FleetTarget target =
        t.fleet_url.empty() ? station::daemon::fleet_target(*t.fleet_config)
                            : db::fleet::parse_fleet_target(t.fleet_url, t.fleet_password);
    db::history::SqliteOptions ro;
    ro.read_only = true;
    const db::history::SqliteRepository local(t.db, ro);
    db::fleet::PgConnection conn(target);
    db::fleet::migrate_fleet(conn);
    // The mark before the read: a run the sender delivers meanwhile is never set apart.
    const db::fleet::ResyncMark mark = db::fleet::begin_resync(conn, station_id);
    const LocalRuns runs = local_runs(local);
    // First set apart what the store holds and this database does not (a replaced database
    // reuses their local ids), then store every run of this one.
    const std::size_t apart = db::fleet::set_apart_runs_not_in(conn, station_id, runs.uuids, mark);
    const db::fleet::UpsertCount n = store_runs(conn, station_id, local, runs.ids, as_json);
    print_resync({{"station_id", station_id},
                  {"fleet", target.redacted()},
                  {"runs", runs.ids.size()},
                  {"written", n.written},
                  {"unchanged", n.unchanged},
                  {"set_apart", apart},
                  {"set_apart_as", apart > 0 ? mark.apart_id : std::string()}},
                 as_json);
    return kOk;
  } catch (const db::history::DbError& e) {
    throw Failure{exit_for_db_error(e.kind()), e.what()};
  }
}

}  // namespace imucal::tools::stationctl
