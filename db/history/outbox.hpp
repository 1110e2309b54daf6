#pragma once
// The replication outbox of a station's SQLite history (schema v7, issue #24 item 2). While the
// station names a fleet database, every change of a run — stored, state changed, a calibration or
// the cross-check stored, a diagnosis, a promotion, a reprocess, an import — adds one entry in the
// same transaction as the change (SQLite triggers, db/history/schema.cpp migration 7), so no write
// path can forget it and a crash cannot separate the two. The sender
// (station/daemon/fleet_sender.hpp) pushes the runs the entries name to the fleet store, then
// removes the entries it has delivered.
#include <cstdint>
#include <string>

#include "db/history/repository.hpp"

namespace imucal::db::history {

struct OutboxEntry {
  std::int64_t seq = 0;  ///< ascending in commit order, never reused
  RunId run_id = 0;
  std::string change;  ///< what happened, for people: "run stored", "state done", "promotion", ...
  TimestampMs at_ms = 0;
};

}  // namespace imucal::db::history
