#pragma once
// The fleet store's PostgreSQL schema and its migrations (issue #24 item 1; db/fleet/README.md
// has the tables). Like the station's SQLite (db/history/schema.hpp): numbered migrations, each
// applied with its row in `fleet_schema_version` inside one transaction; a store newer than this
// software is refused, never written. Concurrent stations migrating at once serialise on an
// advisory lock.
#include "db/fleet/pg_connection.hpp"

namespace imucal::db::fleet {

/// The version this software writes and reads.
constexpr int kFleetSchemaVersion = 4;

/// Brings the store to kFleetSchemaVersion (the role needs CREATE on the schema the first time).
/// Returns the version found before. IncompatibleSchema if the store is newer.
int migrate_fleet(PgConnection& c);

/// For readers (stationctl --fleet, stationweb) and for a sender that may not migrate: the store's
/// version must be exactly kFleetSchemaVersion; otherwise IncompatibleSchema saying what to do.
void check_fleet_version(PgConnection& c);

/// The version stored (0: no fleet schema at all).
int fleet_version(PgConnection& c);

}  // namespace imucal::db::fleet
