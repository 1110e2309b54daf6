#include "tools/stationweb/history_source.hpp"

#include <sys/stat.h>

#include <stdexcept>

#include "db/fleet/fleet_repository.hpp"
#include "db/fleet/pg_fleet_stats.hpp"
#include "db/history/sqlite_fleet_stats.hpp"
#include "db/history/sqlite_repository.hpp"

namespace imucal::tools::stationweb {

namespace {

/// The notice for a file that is no longer the one opened (deleted, moved, or replaced by
/// another inode): the open connections still read the old one.
std::function<std::string()> file_watch(const std::string& path, const struct stat& opened) {
  const dev_t dev = opened.st_dev;
  const ino_t ino = opened.st_ino;
  return [path, dev, ino] {
    struct stat now;
    if (::stat(path.c_str(), &now) != 0)
      return "The history file " + path +
             " is gone (deleted or moved) since stationweb opened it: this page shows what it "
             "held then, and nothing newer will appear. Restart stationweb on the current file.";
    if (now.st_dev != dev || now.st_ino != ino)
      return "The history file " + path +
             " was replaced since stationweb opened it: this page shows the file it opened, not "
             "the new one. Restart stationweb to read the new file.";
    return std::string();
  };
}

}  // namespace

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
  struct stat at_open;
  if (::stat(source.c_str(), &at_open) == 0 && S_ISDIR(at_open.st_mode))
    throw db::history::InvalidInput(source +
                                    ": is a directory, not a history file (--db takes the SQLite "
                                    "file itself, e.g. /var/lib/imucal/history.db)");
  db::history::SqliteOptions options;
  options.read_only = true;
  h.repo = std::make_unique<db::history::SqliteRepository>(source, options);
  h.stats = std::make_unique<db::history::SqliteFleetStats>(source);
  h.label = "SQLite history " + source;
  if (::stat(source.c_str(), &at_open) == 0) h.source_notice = file_watch(source, at_open);
  return h;
}

}  // namespace imucal::tools::stationweb
