#pragma once
// Writes a station's runs into the fleet store (issue #24 item 2): the one write path of the store,
// used by the outbox sender (station/fleet_sender.hpp) and by `stationctl fleet resync`.
//
// Idempotent: a run is keyed by (station id, run UUID); a copy whose revision is not newer than the
// stored one changes nothing (a resend after a lost acknowledgement is a no-op, and a resync racing
// the sender cannot put an older copy over a newer one). A batch is one transaction: all of it is
// in the store, or none.
#include <string>
#include <vector>

#include "db/fleet/pg_connection.hpp"
#include "db/repository.hpp"

namespace imucal::db::fleet {

struct UpsertCount {
  std::size_t written = 0;    ///< inserted, or replaced by a newer revision
  std::size_t unchanged = 0;  ///< already there at this revision or a newer one
};

/// Station ids: 1-64 characters of [A-Za-z0-9._-]. InvalidInput naming the rule otherwise.
void validate_station_id(const std::string& station_id);

/// Stores `runs` (as SqliteRepository::details_of reads them: local ids, UUID, revision) for the
/// station, in one transaction. Conflict if the station already holds another run under one of
/// these local ids with a different UUID (its database was replaced: `stationctl fleet resync`).
UpsertCount upsert_runs(PgConnection& c, const std::string& station_id,
                        const std::vector<RunDetails>& runs);

/// Removes the station's runs whose UUID is not in `keep` (resync: the store's share of the
/// station becomes exactly its SQLite). Returns how many were removed.
std::size_t remove_runs_not_in(PgConnection& c, const std::string& station_id,
                               const std::vector<std::string>& keep);

}  // namespace imucal::db::fleet
