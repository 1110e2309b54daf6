#pragma once
// Writes a station's runs into the fleet store (issue #24 item 2): the one write path of the store,
// used by the outbox sender (station/daemon/fleet_sender.hpp) and by `stationctl fleet resync`.
//
// Idempotent: a run is keyed by (station id, run UUID); a copy whose revision is not newer than the
// stored one changes nothing (a resend after a lost acknowledgement is a no-op, and a resync racing
// the sender cannot put an older copy over a newer one). A batch is one transaction: all of it is
// in the store, or none.
#include <string>
#include <vector>

#include "db/fleet/pg_connection.hpp"
#include "db/history/repository.hpp"

namespace imucal::db::fleet {
using namespace db::history;

struct UpsertCount {
  std::size_t written = 0;    ///< inserted, or replaced by a newer revision
  std::size_t unchanged = 0;  ///< already there at this revision or a newer one
};

/// Station ids: 1-64 characters of [A-Za-z0-9._-]. InvalidInput naming the rule otherwise.
void validate_station_id(const std::string& station_id);

/// Stores `runs` (as SqliteRepository::details_of reads them: local ids, UUID, revision) for the
/// station, in one transaction. Conflict if the station already holds another run under one of
/// these local ids with a different UUID (its database was replaced: `stationctl fleet resync` sets
/// the store's older runs apart).
UpsertCount upsert_runs(PgConnection& c, const std::string& station_id,
                        const std::vector<RunDetails>& runs);

/// A resync's mark, taken before the station's database is read: the store's time then (a run
/// the store received before it was committed in the station's database before it too, so the
/// read sees it if the database still holds it) and the station id that the store's runs the
/// database does not hold are set apart under: `<station id>.previous-<UTC time>`.
struct ResyncMark {
  std::string store_time;  ///< the store's now(), as PostgreSQL prints a timestamptz
  std::string apart_id;
};
ResyncMark begin_resync(PgConnection& c, const std::string& station_id);

/// Resync: the station's runs received before the mark whose UUID is not in `keep` (its database
/// was replaced, or restored from an older copy) move to `mark.apart_id`, in one transaction —
/// kept, never deleted: a calibration record outlives its station's disk, and the station's new
/// database may then reuse their local ids. Returns how many moved.
std::size_t set_apart_runs_not_in(PgConnection& c, const std::string& station_id,
                                  const std::vector<std::string>& keep, const ResyncMark& mark);

}  // namespace imucal::db::fleet
