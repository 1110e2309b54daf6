#include "db/fleet/fleet_schema.hpp"

#include <string>
#include <vector>

#include "db/history/verdict_rule.hpp"

namespace imucal::db::fleet {
using namespace db::history;

namespace {

// An arbitrary constant of ours: the advisory lock under which migrations run.
constexpr const char* kMigrationLock = "SELECT pg_advisory_xact_lock(494355241)";

// Migration 1. A run is keyed by (station_id, run_uuid); local ids are the station's own and are
// kept to resolve reprocessed_from and table_run_id within the station. `revision` lets a newer
// copy replace an older one and never the reverse. Parameter sets are jsonb (the five keys of
// ARCHITECTURE §3) so QA can query them: (params->'gyro_bias_radps'->>2)::float8.
const char* const kFleetMigration1 = R"SQL(
CREATE TABLE runs (
  id                     bigserial PRIMARY KEY,
  station_id             text   NOT NULL CHECK (length(station_id) BETWEEN 1 AND 64),
  run_uuid               text   NOT NULL CHECK (run_uuid ~ '^[0-9a-f]{32}$'),
  local_run_id           bigint NOT NULL,
  revision               bigint NOT NULL,
  serial                 text   NOT NULL,
  operator               text   NOT NULL,
  station                text   NOT NULL,
  sequence_name          text   NOT NULL,
  sequence_sha256        text   NOT NULL,
  software_version       text   NOT NULL,
  started_at_ms          bigint NOT NULL,
  ended_at_ms            bigint,
  state                  text   NOT NULL CHECK (state IN ('preparing', 'running', 'calibrating',
                                  'done', 'review', 'failed', 'aborted', 'interrupted')),
  verdict                text GENERATED ALWAYS AS (
                           CASE state WHEN 'done' THEN 'PASS' WHEN 'review' THEN 'REVIEW'
                           WHEN 'failed' THEN 'FAILED' WHEN 'aborted' THEN 'FAILED'
                           WHEN 'interrupted' THEN 'FAILED' END) STORED,
  failure_reason         text   NOT NULL,
  reasons                jsonb  NOT NULL,
  archive_path           text   NOT NULL,
  archive_sha256         text   NOT NULL,
  reprocessed_from_local bigint,
  table_run_local        bigint,
  slot                   text   NOT NULL,
  capture_json           text   NOT NULL,
  diagnosis_json         text   NOT NULL,
  setting                text   NOT NULL,
  origin                 text   NOT NULL,
  promoted_at_ms         bigint,
  promoted_by            text   NOT NULL,
  promote_reason         text   NOT NULL,
  -- The AINS parameter values in calib::core::param_info order (27, SI), NULL where that result does
  -- not determine the parameter; NULL without an AINS result. Derived from calibrations.params
  -- by the writer: the fleet pages' distributions read one array per run in time order instead
  -- of a jsonb document per run by key (10^6 runs: a week in 14 ms instead of 128 ms).
  ains_values            double precision[],
  received_at            timestamptz NOT NULL DEFAULT now(),
  UNIQUE (station_id, run_uuid),
  UNIQUE (station_id, local_run_id)
);
CREATE INDEX runs_by_serial ON runs (serial, started_at_ms DESC, id DESC);
CREATE INDEX runs_by_time ON runs (started_at_ms, id);
CREATE INDEX runs_by_station_time ON runs (station_id, started_at_ms);
CREATE INDEX runs_by_archive_sha256 ON runs (archive_sha256) WHERE archive_sha256 <> '';
CREATE INDEX runs_live ON runs (state) WHERE state IN ('preparing', 'running', 'calibrating');
CREATE INDEX runs_table_run ON runs (station_id, table_run_local) WHERE table_run_local IS NOT NULL;

CREATE TABLE calibrations (
  run_id       bigint  NOT NULL REFERENCES runs(id) ON DELETE CASCADE,
  method       text    NOT NULL CHECK (method IN ('ains', 'nlsq', 'legacy')),
  params       jsonb   NOT NULL,
  sigma        jsonb   NOT NULL,
  converged    boolean NOT NULL,
  iterations   integer NOT NULL,
  runtime_s    double precision NOT NULL,
  warnings     jsonb   NOT NULL,
  metrics      jsonb,
  body_frame   text    NOT NULL,
  unobservable jsonb   NOT NULL,
  notes        jsonb   NOT NULL,
  PRIMARY KEY (run_id, method)
);

CREATE TABLE crosschecks (
  run_id       bigint PRIMARY KEY REFERENCES runs(id) ON DELETE CASCADE,
  verdict      text   NOT NULL CHECK (verdict IN ('PASS', 'REVIEW')),
  k_sigma      double precision NOT NULL,
  failures     jsonb  NOT NULL,
  not_compared jsonb  NOT NULL
);
)SQL";

// Version 2 (the fleet pages at 10^5 runs and more): the columns the counts per station and day
// and per verdict read, in one narrow index in time order, so both are index-only scans: a run's
// row (reasons, capture and diagnosis texts, the 27 AINS values) is wide, and a year of 10^5 runs
// read from the rows took 90-120 ms for the verdicts alone, 18 ms from this index.
const char* const kFleetMigration2 = R"SQL(
CREATE INDEX runs_by_time_counts ON runs (started_at_ms) INCLUDE (station_id, verdict);
)SQL";

// Version 3 (issue #48 item 7): which of a run's calibrations is its active set, and why, as the
// station's history keeps them (db/history/schema.cpp, migration 9); runs stored before keep AINS.
const char* const kFleetMigration3 = R"SQL(
ALTER TABLE runs ADD COLUMN holding_method text NOT NULL DEFAULT 'ains'
  CHECK (holding_method IN ('ains', 'legacy'));
ALTER TABLE runs ADD COLUMN holding_reason text NOT NULL DEFAULT '';
)SQL";

// Version 4 (issue #50): the verdict says whose a run's end was, as the station's history stores
// it (db/history/schema.cpp, migration 10: FAILED the unit's, STATION-FAULT, ABORTED,
// INTERRUPTED). It is no longer generated from the state: the writer stores the station's verdict,
// and the runs already here are classified by the same rule as the station's migration (their
// state and the reason texts the station writes), so a store whose stations have not resent their
// runs yet counts the same. A table CHECK keeps it consistent with the state.
const std::string kFleetMigration4 = std::string(R"SQL(
DROP INDEX runs_by_time_counts;
ALTER TABLE runs DROP COLUMN verdict;
ALTER TABLE runs ADD COLUMN verdict text CHECK (verdict IS NULL OR verdict IN
  ('PASS', 'REVIEW', 'FAILED', 'STATION-FAULT', 'ABORTED', 'INTERRUPTED'));
UPDATE runs SET verdict = )SQL") + db::history::kVerdictOfEndedRunSql +
                                     R"SQL(
WHERE state IN ('done', 'review', 'failed', 'aborted', 'interrupted');
ALTER TABLE runs ADD CONSTRAINT runs_verdict_fits_state CHECK (coalesce(
  )SQL" + db::history::verdict_fits_state_sql("") +
                                     R"SQL(, false));
CREATE INDEX runs_by_time_counts ON runs (started_at_ms) INCLUDE (station_id, verdict);
)SQL";

struct FleetMigration {
  int version;
  const char* description;
  const char* sql;
};

const std::vector<FleetMigration>& fleet_migrations() {
  static const std::vector<FleetMigration> list = {
      {1, "runs, calibrations (jsonb parameter sets), crosschecks", kFleetMigration1},
      {2, "runs_by_time_counts: the fleet pages' counts read no run row", kFleetMigration2},
      {3, "runs.holding_method, runs.holding_reason: the method a run's active set is",
       kFleetMigration3},
      {4,
       "runs.verdict stored: whose a run's end was (FAILED, STATION-FAULT, ABORTED, INTERRUPTED)",
       kFleetMigration4.c_str()}};
  return list;
}

}  // namespace

int fleet_version(PgConnection& c) {
  const PgResult has = c.exec("SELECT to_regclass('fleet_schema_version') IS NOT NULL", {},
                              "read the schema version");
  if (!has.boolean(0, 0)) return 0;
  const PgResult v = c.exec("SELECT coalesce(max(version), 0) FROM fleet_schema_version", {},
                            "read the schema version");
  return static_cast<int>(v.i64(0, 0));
}

int migrate_fleet(PgConnection& c) {
  PgTransaction tx(c, "schema migration");
  c.exec(kMigrationLock, {}, "schema migration: lock");
  c.exec_plain(
      "CREATE TABLE IF NOT EXISTS fleet_schema_version (version integer PRIMARY KEY, "
      "description text NOT NULL, applied_at timestamptz NOT NULL DEFAULT now())",
      "schema migration: version table");
  const int found = fleet_version(c);
  if (found > kFleetSchemaVersion)
    throw IncompatibleSchema("fleet store " + c.target().redacted() + ": schema version " +
                             std::to_string(found) + " is newer than this software's (" +
                             std::to_string(kFleetSchemaVersion) +
                             "); update this station's software before it sends to this store");
  for (const FleetMigration& m : fleet_migrations()) {
    if (m.version <= found) continue;
    c.exec_plain(m.sql, "schema migration");
    c.exec("INSERT INTO fleet_schema_version (version, description) VALUES ($1, $2)",
           {pg_value(std::int64_t{m.version}), pg_value(m.description)},
           "schema migration: record the version");
  }
  tx.commit();
  return found;
}

void check_fleet_version(PgConnection& c) {
  const int v = fleet_version(c);
  if (v == kFleetSchemaVersion) return;
  if (v == 0)
    throw IncompatibleSchema("fleet store " + c.target().redacted() +
                             ": no fleet schema (no fleet_schema_version table); a station with "
                             "[fleet] url creates it, or `stationctl fleet resync`");
  throw IncompatibleSchema(
      "fleet store " + c.target().redacted() + ": schema version " + std::to_string(v) +
      ", this software reads version " + std::to_string(kFleetSchemaVersion) +
      (v > kFleetSchemaVersion ? ": use a newer version"
                               : ": let a station of this version migrate it"));
}

}  // namespace imucal::db::fleet
