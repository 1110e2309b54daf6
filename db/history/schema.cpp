#include "db/history/schema.hpp"

#include <cstdio>
#include <stdexcept>
#include <string>

#include "db/history/repository.hpp"
#include "db/history/verdict_rule.hpp"

namespace imucal::db::history::schema {

namespace {

// Migration 1: the initial schema. STRICT tables (SQLite >= 3.37) so a wrong type is an error,
// not a silent conversion; CHECK constraints repeat the rules the code enforces, so that even a
// hand-edited database cannot hold a state the code would never write.
const char* const kMigration1 = R"SQL(
CREATE TABLE units (
  id            INTEGER PRIMARY KEY,
  serial        TEXT    NOT NULL UNIQUE
                CHECK (length(serial) BETWEEN 1 AND 32 AND serial NOT GLOB '*[^A-Za-z0-9._-]*'
                       AND substr(serial, 1, 1) GLOB '[A-Za-z0-9]'),
  first_seen_ms INTEGER NOT NULL
) STRICT;

CREATE TABLE runs (
  id               INTEGER PRIMARY KEY AUTOINCREMENT,  -- never reused, even after deletion
  unit_id          INTEGER NOT NULL REFERENCES units(id),
  operator         TEXT    NOT NULL,
  station          TEXT    NOT NULL,
  sequence_name    TEXT    NOT NULL,
  sequence_sha256  TEXT    NOT NULL
                   CHECK (sequence_sha256 = '' OR (length(sequence_sha256) = 64
                          AND sequence_sha256 NOT GLOB '*[^0-9a-f]*')),
  software_version TEXT    NOT NULL,
  started_at_ms    INTEGER NOT NULL,
  ended_at_ms      INTEGER,
  state            TEXT    NOT NULL
                   CHECK (state IN ('preparing', 'running', 'calibrating', 'done', 'review',
                                    'failed', 'aborted', 'interrupted')),
  failure_reason   TEXT    NOT NULL DEFAULT '',
  archive_path     TEXT    NOT NULL DEFAULT '',
  archive_sha256   TEXT    NOT NULL DEFAULT ''
                   CHECK (archive_sha256 = '' OR (length(archive_sha256) = 64
                          AND archive_sha256 NOT GLOB '*[^0-9a-f]*')),
  reprocessed_from INTEGER REFERENCES runs(id),
  -- the end time is set exactly when the run has reached a terminal state
  CHECK ((ended_at_ms IS NOT NULL) =
         (state IN ('done', 'review', 'failed', 'aborted', 'interrupted')))
) STRICT;

-- history(serial): newest first, ties by id
CREATE INDEX runs_by_unit_time ON runs (unit_id, started_at_ms DESC, id DESC);
-- export --since and whole-database export in time order
CREATE INDEX runs_by_time ON runs (started_at_ms, id);
-- start-up recovery and runs_in_state: live runs are few, so a partial index keeps it tiny
CREATE INDEX runs_live ON runs (state) WHERE state IN ('preparing', 'running', 'calibrating');

CREATE TABLE calibrations (
  id                          INTEGER PRIMARY KEY,
  run_id                      INTEGER NOT NULL REFERENCES runs(id),
  method                      TEXT    NOT NULL CHECK (method IN ('ains', 'nlsq')),
  params_json                 TEXT    NOT NULL CHECK (json_valid(params_json)),
  sigma_json                  TEXT    NOT NULL CHECK (json_valid(sigma_json)),
  converged                   INTEGER NOT NULL CHECK (converged IN (0, 1)),
  iterations                  INTEGER NOT NULL,
  runtime_s                   REAL    NOT NULL,
  warnings_json               TEXT    NOT NULL DEFAULT '[]' CHECK (json_valid(warnings_json)),
  -- evaluation metrics (paper §VII): all present or all absent
  orientation_rmse_mdeg       REAL,
  accel_rmse_ug               REAL,
  heading_offset_gamma_np_rad REAL,
  theta_bp_x_rad              REAL,
  theta_bp_y_rad              REAL,
  theta_bp_z_rad              REAL,
  CHECK ((orientation_rmse_mdeg IS NULL) = (accel_rmse_ug IS NULL)
     AND (accel_rmse_ug IS NULL) = (heading_offset_gamma_np_rad IS NULL)
     AND (heading_offset_gamma_np_rad IS NULL) = (theta_bp_x_rad IS NULL)
     AND (theta_bp_x_rad IS NULL) = (theta_bp_y_rad IS NULL)
     AND (theta_bp_y_rad IS NULL) = (theta_bp_z_rad IS NULL)),
  UNIQUE (run_id, method)
) STRICT;

CREATE TABLE crosschecks (
  run_id        INTEGER PRIMARY KEY REFERENCES runs(id),
  verdict       TEXT    NOT NULL CHECK (verdict IN ('PASS', 'REVIEW')),
  k_sigma       REAL    NOT NULL CHECK (k_sigma > 0),
  failures_json TEXT    NOT NULL CHECK (json_valid(failures_json) AND json_type(failures_json) = 'array')
) STRICT;
)SQL";

// Migration 4. SQLite cannot alter a CHECK constraint, so calibrations is rebuilt with the wider
// method set (same columns, same order; rows copied unchanged).
const char* const kMigration4 = R"SQL(
ALTER TABLE runs ADD COLUMN setting TEXT NOT NULL DEFAULT 'factory'
  CHECK (setting IN ('factory', 'land', 'sea'));
ALTER TABLE runs ADD COLUMN origin TEXT NOT NULL DEFAULT '';
ALTER TABLE runs ADD COLUMN promoted_at_ms INTEGER;
ALTER TABLE runs ADD COLUMN promoted_by TEXT NOT NULL DEFAULT '';
ALTER TABLE runs ADD COLUMN promote_reason TEXT NOT NULL DEFAULT '';

CREATE TABLE calibrations_v4 (
  id                          INTEGER PRIMARY KEY,
  run_id                      INTEGER NOT NULL REFERENCES runs(id),
  method                      TEXT    NOT NULL CHECK (method IN ('ains', 'nlsq', 'legacy')),
  params_json                 TEXT    NOT NULL CHECK (json_valid(params_json)),
  sigma_json                  TEXT    NOT NULL CHECK (json_valid(sigma_json)),
  converged                   INTEGER NOT NULL CHECK (converged IN (0, 1)),
  iterations                  INTEGER NOT NULL,
  runtime_s                   REAL    NOT NULL,
  warnings_json               TEXT    NOT NULL DEFAULT '[]' CHECK (json_valid(warnings_json)),
  orientation_rmse_mdeg       REAL,
  accel_rmse_ug               REAL,
  heading_offset_gamma_np_rad REAL,
  theta_bp_x_rad              REAL,
  theta_bp_y_rad              REAL,
  theta_bp_z_rad              REAL,
  CHECK ((orientation_rmse_mdeg IS NULL) = (accel_rmse_ug IS NULL)
     AND (accel_rmse_ug IS NULL) = (heading_offset_gamma_np_rad IS NULL)
     AND (heading_offset_gamma_np_rad IS NULL) = (theta_bp_x_rad IS NULL)
     AND (theta_bp_x_rad IS NULL) = (theta_bp_y_rad IS NULL)
     AND (theta_bp_y_rad IS NULL) = (theta_bp_z_rad IS NULL)),
  UNIQUE (run_id, method)
) STRICT;
INSERT INTO calibrations_v4 SELECT * FROM calibrations;
DROP TABLE calibrations;
ALTER TABLE calibrations_v4 RENAME TO calibrations;
-- active_params: the latest promotion of a unit
CREATE INDEX runs_promoted ON runs (unit_id, promoted_at_ms) WHERE promoted_at_ms IS NOT NULL;
)SQL";

// Migration 5 (issue #19 items 2 and 3). The run verdict is a generated column, a function of
// the state, so no row can show a verdict its state contradicts (before, views showed the
// cross-check's PASS on runs the limits, the gap check or a partial archive had sent to review).
// reasons_json keeps every reason by source; a run stored before keeps its one reason text whole,
// under the source its state or prefix names ("migrated" when neither does). The index serves
// the import's duplicate check (an archive's SHA-256 already stored).
// Migration 6: a run's fixture slot ('' for a station with one unit) and its table run (the run
// id of the first unit captured on the same table motion; NULL for a run of its own).
const char* const kMigration6 = R"SQL(
ALTER TABLE runs ADD COLUMN slot TEXT NOT NULL DEFAULT '' CHECK (length(slot) <= 16);
ALTER TABLE runs ADD COLUMN table_run_id INTEGER REFERENCES runs(id);
CREATE INDEX runs_table_run ON runs(table_run_id) WHERE table_run_id IS NOT NULL;
)SQL";

// Migration 7 (issue #24): replication to the fleet store. Every run gets a UUID (128 random bits,
// 32 lowercase hex digits): with the station id it keys the run in the fleet store, so a resent
// run is the same row. `revision` counts the changes of a run (its row, a calibration or the
// cross-check stored), so the fleet store never lets an older copy of a run replace a newer one
// (a resync racing the daemon's sender). The outbox records every change in the same transaction
// as the change itself (triggers: no write path can forget it) while outbox_state.enabled is 1,
// i.e. while the station names a fleet database; the sender deletes what the fleet store holds.
// The revision triggers' own UPDATE fires no trigger (recursive_triggers is off).
const char* const kMigration7 = R"SQL(
ALTER TABLE runs ADD COLUMN uuid TEXT NOT NULL DEFAULT ''
  CHECK (uuid = '' OR (length(uuid) = 32 AND uuid NOT GLOB '*[^0-9a-f]*'));
ALTER TABLE runs ADD COLUMN revision INTEGER NOT NULL DEFAULT 0;
UPDATE runs SET uuid = lower(hex(randomblob(16)));
CREATE UNIQUE INDEX runs_by_uuid ON runs (uuid);

CREATE TABLE outbox (
  seq    INTEGER PRIMARY KEY AUTOINCREMENT,
  run_id INTEGER NOT NULL REFERENCES runs(id),
  change TEXT    NOT NULL,
  at_ms  INTEGER NOT NULL
) STRICT;
CREATE TABLE outbox_state (
  id      INTEGER PRIMARY KEY CHECK (id = 1),
  enabled INTEGER NOT NULL CHECK (enabled IN (0, 1))
) STRICT;
INSERT INTO outbox_state (id, enabled) VALUES (1, 0);

CREATE TRIGGER runs_revision_on_update AFTER UPDATE ON runs WHEN NEW.revision = OLD.revision
BEGIN UPDATE runs SET revision = OLD.revision + 1 WHERE id = NEW.id; END;
CREATE TRIGGER runs_revision_on_calibration AFTER INSERT ON calibrations
BEGIN UPDATE runs SET revision = revision + 1 WHERE id = NEW.run_id; END;
CREATE TRIGGER runs_revision_on_crosscheck AFTER INSERT ON crosschecks
BEGIN UPDATE runs SET revision = revision + 1 WHERE id = NEW.run_id; END;

CREATE TRIGGER outbox_run_stored AFTER INSERT ON runs
WHEN (SELECT enabled FROM outbox_state) = 1
BEGIN INSERT INTO outbox (run_id, change, at_ms) VALUES (NEW.id,
  CASE WHEN NEW.reprocessed_from IS NOT NULL THEN 'reprocess'
       WHEN NEW.origin <> '' THEN 'import'
       WHEN NEW.setting <> 'factory' THEN 'field run'
       ELSE 'run stored' END,
  CAST(round((julianday('now') - 2440587.5) * 86400000.0) AS INTEGER)); END;
CREATE TRIGGER outbox_run_changed AFTER UPDATE ON runs
WHEN (SELECT enabled FROM outbox_state) = 1 AND NEW.revision = OLD.revision
BEGIN INSERT INTO outbox (run_id, change, at_ms) VALUES (NEW.id,
  CASE WHEN NEW.state <> OLD.state THEN 'state ' || NEW.state
       WHEN NEW.promoted_at_ms IS NOT OLD.promoted_at_ms THEN 'promotion'
       WHEN NEW.diagnosis_json <> OLD.diagnosis_json THEN 'diagnosis'
       ELSE 'run changed' END,
  CAST(round((julianday('now') - 2440587.5) * 86400000.0) AS INTEGER)); END;
CREATE TRIGGER outbox_calibration AFTER INSERT ON calibrations
WHEN (SELECT enabled FROM outbox_state) = 1
BEGIN INSERT INTO outbox (run_id, change, at_ms) VALUES (NEW.run_id, 'calibration ' || NEW.method,
  CAST(round((julianday('now') - 2440587.5) * 86400000.0) AS INTEGER)); END;
CREATE TRIGGER outbox_crosscheck AFTER INSERT ON crosschecks
WHEN (SELECT enabled FROM outbox_state) = 1
BEGIN INSERT INTO outbox (run_id, change, at_ms) VALUES (NEW.run_id, 'cross-check',
  CAST(round((julianday('now') - 2440587.5) * 86400000.0) AS INTEGER)); END;
)SQL";

// Version 8 (issue #24, the fleet pages at 10^5 runs): what QA's aggregates read, kept narrow.
// runs_by_time_station covers the counts per station and day and per verdict (the state) without
// touching the wide runs rows; ains_values holds every AINS result's 27 values as numbers in
// calib::core::param_info order (p00 = accel_bias_mps2[0] ... p26 = table_misalignment_rad[2]; NULL
// where the result does not determine the parameter, CalibrationRecord::unobservable), so a
// parameter's distribution reads 27 REALs per run instead of parsing the parameter-set JSON. The
// view ains_values_computed is the one definition: the migration fills the table from it for the
// results already stored, and the triggers refresh a run's row from it when its AINS result is
// stored, changed or removed, in the same transaction.
const char* const kMigration8 = R"SQL(
CREATE INDEX runs_by_time_station ON runs (started_at_ms, station, state, unit_id);

CREATE VIEW ains_values_computed AS SELECT run_id,
  CASE WHEN unobservable_json <> '[]' AND 'accel_bias_mps2[0]' IN (SELECT value FROM json_each(unobservable_json))
       THEN NULL ELSE json_extract(params_json, '$.accel_bias_mps2[0]') END AS p00,
  CASE WHEN unobservable_json <> '[]' AND 'accel_bias_mps2[1]' IN (SELECT value FROM json_each(unobservable_json))
       THEN NULL ELSE json_extract(params_json, '$.accel_bias_mps2[1]') END AS p01,
  CASE WHEN unobservable_json <> '[]' AND 'accel_bias_mps2[2]' IN (SELECT value FROM json_each(unobservable_json))
       THEN NULL ELSE json_extract(params_json, '$.accel_bias_mps2[2]') END AS p02,
  CASE WHEN unobservable_json <> '[]' AND 'accel_M[0][0]' IN (SELECT value FROM json_each(unobservable_json))
       THEN NULL ELSE json_extract(params_json, '$.accel_M[0][0]') END AS p03,
  CASE WHEN unobservable_json <> '[]' AND 'accel_M[0][1]' IN (SELECT value FROM json_each(unobservable_json))
       THEN NULL ELSE json_extract(params_json, '$.accel_M[0][1]') END AS p04,
  CASE WHEN unobservable_json <> '[]' AND 'accel_M[0][2]' IN (SELECT value FROM json_each(unobservable_json))
       THEN NULL ELSE json_extract(params_json, '$.accel_M[0][2]') END AS p05,
  CASE WHEN unobservable_json <> '[]' AND 'accel_M[1][0]' IN (SELECT value FROM json_each(unobservable_json))
       THEN NULL ELSE json_extract(params_json, '$.accel_M[1][0]') END AS p06,
  CASE WHEN unobservable_json <> '[]' AND 'accel_M[1][1]' IN (SELECT value FROM json_each(unobservable_json))
       THEN NULL ELSE json_extract(params_json, '$.accel_M[1][1]') END AS p07,
  CASE WHEN unobservable_json <> '[]' AND 'accel_M[1][2]' IN (SELECT value FROM json_each(unobservable_json))
       THEN NULL ELSE json_extract(params_json, '$.accel_M[1][2]') END AS p08,
  CASE WHEN unobservable_json <> '[]' AND 'accel_M[2][0]' IN (SELECT value FROM json_each(unobservable_json))
       THEN NULL ELSE json_extract(params_json, '$.accel_M[2][0]') END AS p09,
  CASE WHEN unobservable_json <> '[]' AND 'accel_M[2][1]' IN (SELECT value FROM json_each(unobservable_json))
       THEN NULL ELSE json_extract(params_json, '$.accel_M[2][1]') END AS p10,
  CASE WHEN unobservable_json <> '[]' AND 'accel_M[2][2]' IN (SELECT value FROM json_each(unobservable_json))
       THEN NULL ELSE json_extract(params_json, '$.accel_M[2][2]') END AS p11,
  CASE WHEN unobservable_json <> '[]' AND 'gyro_bias_radps[0]' IN (SELECT value FROM json_each(unobservable_json))
       THEN NULL ELSE json_extract(params_json, '$.gyro_bias_radps[0]') END AS p12,
  CASE WHEN unobservable_json <> '[]' AND 'gyro_bias_radps[1]' IN (SELECT value FROM json_each(unobservable_json))
       THEN NULL ELSE json_extract(params_json, '$.gyro_bias_radps[1]') END AS p13,
  CASE WHEN unobservable_json <> '[]' AND 'gyro_bias_radps[2]' IN (SELECT value FROM json_each(unobservable_json))
       THEN NULL ELSE json_extract(params_json, '$.gyro_bias_radps[2]') END AS p14,
  CASE WHEN unobservable_json <> '[]' AND 'gyro_M[0][0]' IN (SELECT value FROM json_each(unobservable_json))
       THEN NULL ELSE json_extract(params_json, '$.gyro_M[0][0]') END AS p15,
  CASE WHEN unobservable_json <> '[]' AND 'gyro_M[0][1]' IN (SELECT value FROM json_each(unobservable_json))
       THEN NULL ELSE json_extract(params_json, '$.gyro_M[0][1]') END AS p16,
  CASE WHEN unobservable_json <> '[]' AND 'gyro_M[0][2]' IN (SELECT value FROM json_each(unobservable_json))
       THEN NULL ELSE json_extract(params_json, '$.gyro_M[0][2]') END AS p17,
  CASE WHEN unobservable_json <> '[]' AND 'gyro_M[1][0]' IN (SELECT value FROM json_each(unobservable_json))
       THEN NULL ELSE json_extract(params_json, '$.gyro_M[1][0]') END AS p18,
  CASE WHEN unobservable_json <> '[]' AND 'gyro_M[1][1]' IN (SELECT value FROM json_each(unobservable_json))
       THEN NULL ELSE json_extract(params_json, '$.gyro_M[1][1]') END AS p19,
  CASE WHEN unobservable_json <> '[]' AND 'gyro_M[1][2]' IN (SELECT value FROM json_each(unobservable_json))
       THEN NULL ELSE json_extract(params_json, '$.gyro_M[1][2]') END AS p20,
  CASE WHEN unobservable_json <> '[]' AND 'gyro_M[2][0]' IN (SELECT value FROM json_each(unobservable_json))
       THEN NULL ELSE json_extract(params_json, '$.gyro_M[2][0]') END AS p21,
  CASE WHEN unobservable_json <> '[]' AND 'gyro_M[2][1]' IN (SELECT value FROM json_each(unobservable_json))
       THEN NULL ELSE json_extract(params_json, '$.gyro_M[2][1]') END AS p22,
  CASE WHEN unobservable_json <> '[]' AND 'gyro_M[2][2]' IN (SELECT value FROM json_each(unobservable_json))
       THEN NULL ELSE json_extract(params_json, '$.gyro_M[2][2]') END AS p23,
  CASE WHEN unobservable_json <> '[]' AND 'table_misalignment_rad[0]' IN (SELECT value FROM json_each(unobservable_json))
       THEN NULL ELSE json_extract(params_json, '$.table_misalignment_rad[0]') END AS p24,
  CASE WHEN unobservable_json <> '[]' AND 'table_misalignment_rad[1]' IN (SELECT value FROM json_each(unobservable_json))
       THEN NULL ELSE json_extract(params_json, '$.table_misalignment_rad[1]') END AS p25,
  CASE WHEN unobservable_json <> '[]' AND 'table_misalignment_rad[2]' IN (SELECT value FROM json_each(unobservable_json))
       THEN NULL ELSE json_extract(params_json, '$.table_misalignment_rad[2]') END AS p26
FROM calibrations WHERE method = 'ains';

CREATE TABLE ains_values (
  run_id INTEGER PRIMARY KEY REFERENCES runs(id),
  p00 REAL,
  p01 REAL,
  p02 REAL,
  p03 REAL,
  p04 REAL,
  p05 REAL,
  p06 REAL,
  p07 REAL,
  p08 REAL,
  p09 REAL,
  p10 REAL,
  p11 REAL,
  p12 REAL,
  p13 REAL,
  p14 REAL,
  p15 REAL,
  p16 REAL,
  p17 REAL,
  p18 REAL,
  p19 REAL,
  p20 REAL,
  p21 REAL,
  p22 REAL,
  p23 REAL,
  p24 REAL,
  p25 REAL,
  p26 REAL
) STRICT;
INSERT INTO ains_values SELECT * FROM ains_values_computed;

CREATE TRIGGER ains_values_on_insert AFTER INSERT ON calibrations WHEN NEW.method = 'ains'
BEGIN INSERT OR REPLACE INTO ains_values SELECT * FROM ains_values_computed
  WHERE run_id = NEW.run_id; END;
CREATE TRIGGER ains_values_on_update
AFTER UPDATE OF run_id, method, params_json, unobservable_json ON calibrations
BEGIN
  DELETE FROM ains_values WHERE run_id IN (OLD.run_id, NEW.run_id);
  INSERT INTO ains_values SELECT * FROM ains_values_computed
    WHERE run_id IN (OLD.run_id, NEW.run_id);
END;
CREATE TRIGGER ains_values_on_delete AFTER DELETE ON calibrations WHEN OLD.method = 'ains'
BEGIN DELETE FROM ains_values WHERE run_id = OLD.run_id; END;
)SQL";

// Version 9 (issue #48 item 7): which of a run's calibrations is its active set, and why. AINS
// but on a land run below navigation grade whose rests AINS cannot hold as the legacy fit does
// (calib/pipeline/holding_method.hpp); every run stored before keeps AINS, as it was active then.
const char* const kMigration9 = R"SQL(
ALTER TABLE runs ADD COLUMN holding_method TEXT NOT NULL DEFAULT 'ains'
  CHECK (holding_method IN ('ains', 'legacy'));
ALTER TABLE runs ADD COLUMN holding_reason TEXT NOT NULL DEFAULT '';
)SQL";

// Version 10 (issue #50): a run's verdict says whose its end was. Until now it was generated from
// the state, and every failed, aborted or interrupted run was the unit's FAILED — a table that
// could not be reached, a CAN bus gone, a full disk, an operator's abort. The verdict becomes a
// stored column (SQLite drops a VIRTUAL generated column in place) written by finish_run; the
// migration classifies the runs already stored by their state and the reason texts the station
// has always written for them (station/run/run_session.cpp, capture.cpp, run_controller.cpp):
//   done → PASS, review → REVIEW, interrupted → INTERRUPTED;
//   aborted with "table: …" (a turntable fault ended the capture; an operator's own abort starts
//   with the operator's words) → STATION-FAULT, other aborted → ABORTED;
//   failed with "archive: …", "import: cannot store the archive…", or a capture fault of the CAN
//   channel, the bus or the archive writer ("CAN channel error", "went bus-off", "run archive
//   write failed", "the CAN channel is closed", a channel URI that could not be opened) →
//   STATION-FAULT; every other failed (data checks, the calibration, the unit's stream) → FAILED.
// Triggers keep the verdict consistent with the state (a CHECK cannot be added to a table). The
// updates count as a change of each ended run (revision, outbox), so a fleet store that is sent
// the runs again takes the new verdicts. runs_by_time_station covers the verdict instead of the
// state: the fleet pages count verdicts.
std::string verdict_trigger(const std::string& name, const std::string& event) {
  return "CREATE TRIGGER " + name + " BEFORE " + event + " ON runs\nWHEN NOT coalesce(" +
         verdict_fits_state_sql("NEW.") +
         ", 0)\nBEGIN SELECT RAISE(ABORT, 'runs.verdict does not fit the run''s state'); END;\n";
}
const std::string kMigration10 = std::string(R"SQL(
DROP INDEX runs_by_time_station;
ALTER TABLE runs DROP COLUMN verdict;
ALTER TABLE runs ADD COLUMN verdict TEXT CHECK (verdict IS NULL OR verdict IN
  ('PASS', 'REVIEW', 'FAILED', 'STATION-FAULT', 'ABORTED', 'INTERRUPTED'));
UPDATE runs SET verdict = )SQL") +
                                 kVerdictOfEndedRunSql + R"SQL(
WHERE state IN ('done', 'review', 'failed', 'aborted', 'interrupted');
CREATE INDEX runs_by_time_station ON runs (started_at_ms, station, verdict, unit_id);
)SQL" + verdict_trigger("runs_verdict_fits_state_on_insert", "INSERT") +
                                 verdict_trigger("runs_verdict_fits_state_on_update",
                                                 "UPDATE OF state, verdict");

const char* const kMigration5 = R"SQL(
ALTER TABLE runs ADD COLUMN verdict TEXT GENERATED ALWAYS AS (
  CASE state WHEN 'done' THEN 'PASS' WHEN 'review' THEN 'REVIEW'
             WHEN 'failed' THEN 'FAILED' WHEN 'aborted' THEN 'FAILED'
             WHEN 'interrupted' THEN 'FAILED' END) VIRTUAL;
ALTER TABLE runs ADD COLUMN reasons_json TEXT NOT NULL DEFAULT '[]'
  CHECK (json_valid(reasons_json) AND json_type(reasons_json) = 'array');
UPDATE runs SET reasons_json = json_array(json_object(
  'source', CASE
    WHEN state IN ('aborted', 'interrupted') THEN state
    WHEN state = 'failed' THEN 'error'
    WHEN failure_reason LIKE 'cross-check%' THEN 'cross-check'
    WHEN failure_reason LIKE 'limits:%' THEN 'limits'
    WHEN failure_reason LIKE 'sim-to-real gap%' THEN 'gap'
    WHEN failure_reason LIKE 'partial archive%' THEN 'partial archive'
    WHEN failure_reason LIKE 'sea:%' THEN 'field'
    ELSE 'migrated' END,
  'text', failure_reason))
WHERE failure_reason <> '';
CREATE INDEX runs_by_archive_sha256 ON runs (archive_sha256) WHERE archive_sha256 <> '';

ALTER TABLE calibrations ADD COLUMN body_frame TEXT NOT NULL DEFAULT 'housing'
  CHECK (body_frame IN ('housing', 'accel_symmetric'));
ALTER TABLE calibrations ADD COLUMN unobservable_json TEXT NOT NULL DEFAULT '[]'
  CHECK (json_valid(unobservable_json) AND json_type(unobservable_json) = 'array');
ALTER TABLE calibrations ADD COLUMN notes_json TEXT NOT NULL DEFAULT '[]'
  CHECK (json_valid(notes_json) AND json_type(notes_json) = 'array');
ALTER TABLE crosschecks ADD COLUMN not_compared_json TEXT NOT NULL DEFAULT '[]'
  CHECK (json_valid(not_compared_json) AND json_type(not_compared_json) = 'array');
-- Field results stored before v5: every one was in the triad's frame without the table terms
-- (calib/ains/ains.cpp describe_field_frame, calib/legacy/legacy.cpp), and their cross-check skipped those.
UPDATE calibrations SET body_frame = 'accel_symmetric',
  unobservable_json = '["table_misalignment_rad[0]","table_misalignment_rad[1]","table_misalignment_rad[2]"]',
  notes_json = json_array(
    'housing orientation: not observable ' ||
      (SELECT CASE setting WHEN 'sea' THEN 'at sea' ELSE 'on land' END FROM runs
       WHERE runs.id = calibrations.run_id) ||
      ' (no attitude reference); misalignments are relative to the accelerometer triad''s own '
      || 'orthogonal frame',
    'table misalignment: no table, not estimated')
WHERE run_id IN (SELECT id FROM runs WHERE setting <> 'factory');
UPDATE crosschecks SET
  not_compared_json = '["table_misalignment_rad[0]","table_misalignment_rad[1]","table_misalignment_rad[2]"]'
WHERE run_id IN (SELECT id FROM runs WHERE setting <> 'factory');
)SQL";

int pragma_int(sqlite3* db, const char* sql, const std::string& path) {
  sqlite3_stmt* st = nullptr;
  int rc = sqlite3_prepare_v2(db, sql, -1, &st, nullptr);
  if (rc != SQLITE_OK) throw_sqlite(db, rc, path, sql);
  rc = sqlite3_step(st);
  if (rc != SQLITE_ROW) {
    sqlite3_finalize(st);
    throw_sqlite(db, rc, path, sql);
  }
  const int v = sqlite3_column_int(st, 0);
  sqlite3_finalize(st);
  return v;
}

std::string hex32(int v) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "0x%08x", static_cast<unsigned>(v));
  return buf;
}

}  // namespace

int check_compatible(sqlite3* db, const std::string& path, int latest) {
  const int found = user_version(db, path);
  const int app_id = pragma_int(db, "PRAGMA application_id", path);
  if (found > latest)
    throw IncompatibleSchema(path + ": database schema version " + std::to_string(found) +
                             " is newer than this software supports (" + std::to_string(latest) +
                             "); refusing to open it — use the software version that wrote it "
                             "or a newer one");
  if (app_id != 0 && app_id != kApplicationId)
    throw IncompatibleSchema(path + ": not a calibration-history database (application_id " +
                             hex32(app_id) + ", expected " + hex32(kApplicationId) + ")");
  if (found == 0) {
    const int tables =
        pragma_int(db, "SELECT count(*) FROM sqlite_schema WHERE name NOT LIKE 'sqlite_%'", path);
    if (tables > 0)
      throw IncompatibleSchema(path + ": database has " + std::to_string(tables) +
                               " table(s) but no schema version (user_version 0); it was not "
                               "created by this software — refusing to modify it");
  }
  return found;
}

const std::vector<Migration>& migrations() {
  static const std::vector<Migration> list = {
      {1, "initial schema: units, runs, calibrations, crosschecks", kMigration1},
      // Version 2 (station daemon): the capture counters of a run (frames, lost/filled samples,
      // ...) as a JSON object text, so QA sees what the link did to a run's data.
      {2, "runs.capture_json: capture counters of a run",
       "ALTER TABLE runs ADD COLUMN capture_json TEXT NOT NULL DEFAULT '' "
       "CHECK (capture_json = '' OR json_valid(capture_json));"},
      // Version 3 (gap diagnosis, issue #8): the summary of the run's sim-to-real gap diagnosis
      // (verdict, best effect with magnitude and σ, overall gap), so QA sees per serial and across
      // units which unmodelled effects recur.
      {3, "runs.diagnosis_json: gap diagnosis summary of a run",
       "ALTER TABLE runs ADD COLUMN diagnosis_json TEXT NOT NULL DEFAULT '' "
       "CHECK (diagnosis_json = '' OR json_valid(diagnosis_json));"},
      // Version 4 (field settings, issue #9): where a run's data were recorded, imported field
      // runs' origin, QA's promotion of a field run, and the legacy method's results.
      {4, "runs.setting/origin/promotion; calibrations.method gains 'legacy'", kMigration4},
      // Version 5 (issue #19): the run verdict (PASS/REVIEW/FAILED from the state) and its
      // reasons by source; the archive SHA-256 index for the import's duplicate check.
      {5,
       "runs.verdict (generated), runs.reasons_json; archive SHA-256 index; calibrations "
       "body_frame/unobservable/notes; crosschecks.not_compared",
       kMigration5},
      // Version 6 (issue #23): several units on one table run. Each unit is a run of its own; the
      // fixture slot it sat in, and the first unit's run as the table run that joins the siblings.
      {6, "runs.slot, runs.table_run_id: several units per table run", kMigration6},
      {7, "runs.uuid, runs.revision, outbox: replication to the fleet store", kMigration7},
      {8, "runs_by_time_station index, ains_values: the fleet pages' aggregates", kMigration8},
      {9, "runs.holding_method, runs.holding_reason: the method a run's active set is",
       kMigration9},
      {10,
       "runs.verdict stored: whose a run's end was (FAILED, STATION-FAULT, ABORTED, INTERRUPTED)",
       kMigration10.c_str()},
  };
  return list;
}

[[noreturn]] void throw_sqlite(sqlite3* db, int rc, const std::string& path,
                               const std::string& context) {
  std::string msg = path + ": " + context + ": ";
  msg += db ? sqlite3_errmsg(db) : sqlite3_errstr(rc);
  switch (rc & 0xff) {
    case SQLITE_BUSY:
    case SQLITE_LOCKED:
      throw Busy(msg + " (another connection holds the database; retry later)");
    case SQLITE_CORRUPT:
    case SQLITE_NOTADB:
      throw Corrupt(msg);
    case SQLITE_READONLY:
      throw ReadOnly(msg);
    case SQLITE_CONSTRAINT:
      throw Conflict(msg);
    default:
      throw IoError(msg);
  }
}

void exec(sqlite3* db, const char* sql, const std::string& path, const std::string& context) {
  char* err = nullptr;
  const int rc = sqlite3_exec(db, sql, nullptr, nullptr, &err);
  if (rc != SQLITE_OK) {
    sqlite3_free(err);
    throw_sqlite(db, rc, path, context);
  }
}

int user_version(sqlite3* db, const std::string& path) {
  return pragma_int(db, "PRAGMA user_version", path);
}

int migrate(sqlite3* db, const std::string& path, const std::vector<Migration>& list) {
  const int latest = list.empty() ? 0 : list.back().version;
  // Refuse before touching anything, then again inside the write transaction (another process
  // may have migrated in between).
  for (std::size_t i = 0; i < list.size(); ++i)
    if (list[i].version != static_cast<int>(i) + 1)
      throw std::logic_error("schema migrations must be numbered 1, 2, ... without gaps");
  if (check_compatible(db, path, latest) == latest &&
      pragma_int(db, "PRAGMA application_id", path) == kApplicationId)
    return latest;  // current: no write lock needed
  exec(db, "BEGIN IMMEDIATE", path, "schema migration: begin");
  try {
    const int found = check_compatible(db, path, latest);
    const int app_id = pragma_int(db, "PRAGMA application_id", path);
    for (const Migration& m : list) {
      if (m.version <= found) continue;
      exec(db, m.sql, path, "migration " + std::to_string(m.version) + " (" + m.description + ")");
      // PRAGMA arguments cannot be bound; the number is our own constant, not input.
      const std::string bump = "PRAGMA user_version = " + std::to_string(m.version);
      exec(db, bump.c_str(), path, "migration " + std::to_string(m.version) + ": set user_version");
    }
    if (app_id == 0) {
      const std::string set_app = "PRAGMA application_id = " + std::to_string(kApplicationId);
      exec(db, set_app.c_str(), path, "schema migration: set application_id");
    }
    exec(db, "COMMIT", path, "schema migration: commit");
    return found;
  } catch (...) {
    sqlite3_exec(db, "ROLLBACK", nullptr, nullptr, nullptr);
    throw;
  }
}

void check_version_readable(sqlite3* db, const std::string& path) {
  const int v = user_version(db, path);
  if (v == kSchemaVersion) {
    const int app_id = pragma_int(db, "PRAGMA application_id", path);
    if (app_id != kApplicationId)
      throw IncompatibleSchema(path + ": not a calibration-history database (application_id " +
                               hex32(app_id) + ")");
    return;
  }
  if (v > kSchemaVersion)
    throw IncompatibleSchema(path + ": database schema version " + std::to_string(v) +
                             " is newer than this software supports (" +
                             std::to_string(kSchemaVersion) + "); use a newer version to read it");
  if (v == 0)
    throw IncompatibleSchema(path +
                             ": no calibration-history schema (user_version 0); the "
                             "station daemon creates it when it first opens the database");
  throw IncompatibleSchema(path + ": database schema version " + std::to_string(v) +
                           " is older than this software's " + std::to_string(kSchemaVersion) +
                           "; open it read-write once (start the station daemon) to migrate it");
}

}  // namespace imucal::db::history::schema
