#include "db/fleet/fleet_writer.hpp"

#include <algorithm>
#include <nlohmann/json.hpp>

#include "calib/core/param_set.hpp"
#include "db/fleet/fleet_codec.hpp"
#include "db/history/export.hpp"

namespace imucal::db::fleet {
using namespace db::history;

namespace {

using nlohmann::json;

// The upsert: a newer revision replaces every column; an equal or older one changes nothing and
// returns no row (so the children are left alone too).
const char* const kSqlUpsertRun = R"SQL(
INSERT INTO runs (station_id, run_uuid, local_run_id, revision, serial, operator, station,
  sequence_name, sequence_sha256, software_version, started_at_ms, ended_at_ms, state,
  failure_reason, reasons, archive_path, archive_sha256, reprocessed_from_local, table_run_local,
  slot, capture_json, diagnosis_json, setting, origin, promoted_at_ms, promoted_by, promote_reason,
  ains_values, holding_method, holding_reason, verdict)
VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, $10, $11, $12, $13, $14, $15::jsonb, $16, $17, $18,
  $19, $20, $21, $22, $23, $24, $25, $26, $27, $28::double precision[], $29, $30, $31)
ON CONFLICT (station_id, run_uuid) DO UPDATE SET revision = EXCLUDED.revision,
  serial = EXCLUDED.serial, operator = EXCLUDED.operator, station = EXCLUDED.station,
  sequence_name = EXCLUDED.sequence_name, sequence_sha256 = EXCLUDED.sequence_sha256,
  software_version = EXCLUDED.software_version, started_at_ms = EXCLUDED.started_at_ms,
  ended_at_ms = EXCLUDED.ended_at_ms, state = EXCLUDED.state,
  failure_reason = EXCLUDED.failure_reason, reasons = EXCLUDED.reasons,
  archive_path = EXCLUDED.archive_path, archive_sha256 = EXCLUDED.archive_sha256,
  reprocessed_from_local = EXCLUDED.reprocessed_from_local,
  table_run_local = EXCLUDED.table_run_local, slot = EXCLUDED.slot,
  capture_json = EXCLUDED.capture_json, diagnosis_json = EXCLUDED.diagnosis_json,
  setting = EXCLUDED.setting, origin = EXCLUDED.origin, promoted_at_ms = EXCLUDED.promoted_at_ms,
  promoted_by = EXCLUDED.promoted_by, promote_reason = EXCLUDED.promote_reason,
  ains_values = EXCLUDED.ains_values, holding_method = EXCLUDED.holding_method,
  holding_reason = EXCLUDED.holding_reason, verdict = EXCLUDED.verdict, received_at = now()
WHERE runs.revision < EXCLUDED.revision
RETURNING id
)SQL";
const char* const kSqlInsertCal =
    "INSERT INTO calibrations (run_id, method, params, sigma, converged, iterations, runtime_s, "
    "warnings, metrics, body_frame, unobservable, notes) VALUES ($1, $2, $3::jsonb, $4::jsonb, "
    "$5, $6, $7, $8::jsonb, $9::jsonb, $10, $11::jsonb, $12::jsonb)";
const char* const kSqlInsertCrosscheck =
    "INSERT INTO crosschecks (run_id, verdict, k_sigma, failures, not_compared) "
    "VALUES ($1, $2, $3, $4::jsonb, $5::jsonb)";

/// The run's AINS values as a PostgreSQL array literal (calib::core::param_info order, NULL where
/// the result lists the parameter as unobservable); none without an AINS result.
PgParam ains_values(const RunDetails& d) {
  for (const CalibrationRecord& c : d.calibrations) {
    if (c.method != Method::kAins) continue;
    const calib::core::ParamVector x = c.params.to_vector();
    std::string out = "{";
    for (int i = 0; i < calib::core::ParamSet::kSize; ++i) {
      const std::string& name = calib::core::param_info(i).name;
      const bool unknown =
          std::find(c.unobservable.begin(), c.unobservable.end(), name) != c.unobservable.end();
      out += (i ? "," : "") + (unknown ? std::string("NULL") : *pg_value(x(i)));
    }
    return out + "}";
  }
  return std::nullopt;
}

std::vector<PgParam> run_values(const std::string& station_id, const RunDetails& d) {
  const RunRecord& r = d.run;
  return {pg_value(station_id),
          pg_value(r.uuid),
          pg_value(r.run_id),
          pg_value(r.revision),
          pg_value(r.serial),
          pg_value(r.operator_name),
          pg_value(r.station),
          pg_value(r.sequence_name),
          pg_value(r.sequence_sha256),
          pg_value(r.software_version),
          pg_value(r.started_at_ms),
          pg_value(r.ended_at_ms),
          pg_value(to_string(r.state)),
          pg_value(r.failure_reason),
          pg_value(reasons_json(r.reasons).dump()),
          pg_value(r.archive_path),
          pg_value(r.archive_sha256),
          pg_value(r.reprocessed_from),
          pg_value(r.table_run_id),
          pg_value(r.slot),
          pg_value(r.capture_json),
          pg_value(r.diagnosis_json),
          pg_value(calib::core::setting_name(r.setting)),
          pg_value(r.origin),
          pg_value(r.promoted_at_ms),
          pg_value(r.promoted_by),
          pg_value(r.promote_reason),
          ains_values(d),
          pg_value(to_string(r.holding_method)),
          pg_value(r.holding_reason),
          r.verdict ? pg_value(std::string(to_string(*r.verdict))) : PgParam(std::nullopt)};
}

void replace_children(PgConnection& c, std::int64_t fleet_id, const RunDetails& d) {
  const PgParam id = pg_value(fleet_id);
  c.exec("DELETE FROM calibrations WHERE run_id = $1", {id}, "store calibrations");
  c.exec("DELETE FROM crosschecks WHERE run_id = $1", {id}, "store the cross-check");
  for (const CalibrationRecord& k : d.calibrations) {
    const PgParam metrics =
        k.metrics ? pg_value(metrics_json(*k.metrics).dump()) : PgParam(std::nullopt);
    c.exec(kSqlInsertCal,
           {id, pg_value(to_string(k.method)), pg_value(params_json(k.params).dump()),
            pg_value(params_json(k.sigma).dump()), pg_value(k.converged),
            pg_value(std::int64_t{k.iterations}), pg_value(k.runtime_s),
            pg_value(json(k.warnings).dump()), metrics, pg_value(to_string(k.body_frame)),
            pg_value(json(k.unobservable).dump()), pg_value(json(k.notes).dump())},
           "store a calibration");
  }
  if (d.crosscheck) {
    const json x = crosscheck_json(*d.crosscheck);
    c.exec(kSqlInsertCrosscheck,
           {id, pg_value(to_string(d.crosscheck->verdict)), pg_value(d.crosscheck->k_sigma),
            pg_value(x["failures"].dump()), pg_value(x["not_compared"].dump())},
           "store the cross-check");
  }
}

}  // namespace

void validate_station_id(const std::string& id) {
  bool ok = !id.empty() && id.size() <= 64;
  for (char ch : id)
    ok =
        ok && (std::isalnum(static_cast<unsigned char>(ch)) || ch == '.' || ch == '_' || ch == '-');
  if (!ok)
    throw InvalidInput("station id \"" + id +
                       "\": 1-64 characters of A-Z, a-z, 0-9, '.', '_' and '-'");
}

UpsertCount upsert_runs(PgConnection& c, const std::string& station_id,
                        const std::vector<RunDetails>& runs) {
  validate_station_id(station_id);
  UpsertCount n;
  PgTransaction tx(c, "store runs");
  for (const RunDetails& d : runs) {
    if (d.run.uuid.size() != 32)
      throw InvalidInput("station " + station_id + " run " + std::to_string(d.run.run_id) +
                         ": no run UUID (open the station's database read-write once to migrate)");
    PgResult r = [&] {
      try {
        return c.exec(kSqlUpsertRun, run_values(station_id, d), "store a run");
      } catch (const Conflict& e) {
        throw Conflict(std::string(e.what()) + " (station " + station_id + ", run " +
                       std::to_string(d.run.run_id) +
                       ": the store holds another run under this local id; was the station's "
                       "database replaced? `stationctl fleet resync` sets the store's older runs "
                       "apart, kept, and sends this database's)");
      }
    }();
    if (r.rows() == 0) {
      ++n.unchanged;
      continue;
    }
    replace_children(c, r.i64(0, 0), d);
    ++n.written;
  }
  tx.commit();
  return n;
}

ResyncMark begin_resync(PgConnection& c, const std::string& station_id) {
  validate_station_id(station_id);
  const PgResult r =
      c.exec("SELECT now()::text, to_char(now() AT TIME ZONE 'UTC', 'YYYYMMDD\"T\"HH24MISS\"Z\"')",
             {}, "resync: the store's time");
  const std::string suffix = ".previous-" + r.text(0, 1);
  ResyncMark m;
  m.store_time = r.text(0, 0);
  m.apart_id = station_id.substr(0, 64 - suffix.size()) + suffix;
  validate_station_id(m.apart_id);
  return m;
}

std::size_t set_apart_runs_not_in(PgConnection& c, const std::string& station_id,
                                  const std::vector<std::string>& keep, const ResyncMark& mark) {
  validate_station_id(station_id);
  validate_station_id(mark.apart_id);
  PgTransaction tx(c, "resync: set apart the runs the station no longer holds");
  const PgResult r = [&] {
    try {
      return c.exec(
          "UPDATE runs SET station_id = $4 WHERE station_id = $1 AND received_at < "
          "$3::timestamptz AND NOT (run_uuid = ANY ($2::text[])) RETURNING id",
          {pg_value(station_id), pg_text_array(keep), pg_value(mark.store_time),
           pg_value(mark.apart_id)},
          "resync: set runs apart");
    } catch (const Conflict& e) {
      throw Conflict(std::string(e.what()) + " (station " + mark.apart_id +
                     " already holds runs under the same local ids: resync again in a second)");
    }
  }();
  tx.commit();
  return static_cast<std::size_t>(r.rows());
}

}  // namespace imucal::db::fleet
