#include "tools/stationweb/history_source.hpp"

#include <stdexcept>

#include "db/sqlite_fleet_stats.hpp"
#include "db/sqlite_repository.hpp"

namespace imucal::stationweb {

History open_history(const std::string& source) {
  if (source.empty()) throw std::invalid_argument("no history given (--db FILE)");
  if (source.rfind("postgresql://", 0) == 0 || source.rfind("postgres://", 0) == 0)
    throw std::invalid_argument(
        "the PostgreSQL fleet store is not supported by this build yet; give the path of a "
        "station's SQLite history");
  History h;
  db::SqliteOptions options;
  options.read_only = true;
  h.repo = std::make_unique<db::SqliteRepository>(source, options);
  h.stats = std::make_unique<db::SqliteFleetStats>(source);
  h.label = "SQLite history " + source;
  return h;
}

}  // namespace imucal::stationweb
