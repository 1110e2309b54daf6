#include "tools/stationweb/history_source.hpp"

#include <stdexcept>

#include "db/fleet/fleet_repository.hpp"
#include "db/fleet/pg_fleet_stats.hpp"
#include "db/history/sqlite_fleet_stats.hpp"
#include "db/history/sqlite_repository.hpp"

namespace imucal::tools::stationweb {

History open_history(const std::string& source, const std::string& password) {
  if (source.empty()) throw std::invalid_argument("no history given (--db FILE or URL)");
  History h;
  if (source.rfind("postgresql://", 0) == 0 || source.rfind("postgres://", 0) == 0) {
    // The fleet store: its read side and its aggregates, each on a connection of its own. Log in
    // with a role that has no write grant (db/fleet/README.md "Roles").
    const db::fleet::FleetTarget target = db::fleet::parse_fleet_target(source, password);
    h.repo = std::make_unique<db::fleet::FleetRepository>(target);
    h.stats = std::make_unique<db::fleet::PgFleetStats>(target);
    h.label = "fleet store " + target.redacted();
    return h;
  }
  db::history::SqliteOptions options;
  options.read_only = true;
  h.repo = std::make_unique<db::history::SqliteRepository>(source, options);
  h.stats = std::make_unique<db::history::SqliteFleetStats>(source);
  h.label = "SQLite history " + source;
  return h;
}

}  // namespace imucal::tools::stationweb
