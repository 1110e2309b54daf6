#pragma once
// The fleet store as a db::history::Repository (issue #24 items 1 and 3): the read side of the
// interface over PostgreSQL, so `stationctl --fleet URL history|show|params|export` and stationweb
// print exactly what they print for a station's SQLite. Runs of every station: a run's id here is
// the store's own (RunRecord::run_id); its station is RunRecord::station; reprocessed_from and
// table_run_id are translated to the store's ids (within the same station).
//
// Writes: the store is written only by each station's outbox sender (db/fleet/fleet_writer.hpp);
// every write method of the interface throws db::history::ReadOnly saying so. Readers should log in
// with a role that has no write grant at all (db/fleet/README.md): the server, not this class, is
// what keeps the QA view from writing.
//
// The active calibration of a serial across the fleet: the latest done+PASS factory run of any
// station (origin ''), unless a promotion made after it ended wins — the station's rule
// (db/history/repository.hpp) with every station's runs.
//
// Thread safety: calls are serialised on one connection (mutex).
#include <memory>
#include <mutex>
#include <optional>

#include "db/fleet/pg_connection.hpp"
#include "db/history/repository.hpp"

namespace imucal::db::fleet {
using namespace db::history;

class FleetRepository final : public Repository {
 public:
  /// Connects and checks the schema version (exactly kFleetSchemaVersion): IoError,
  /// IncompatibleSchema naming the redacted address.
  explicit FleetRepository(const FleetTarget& target);
  ~FleetRepository() override;

  RunId create_run(const NewRun& run) override;
  void update_run_state(RunId run_id, RunState state, const std::string& reason = {}) override;
  void finish_run(RunId run_id, const RunCompletion& completion) override;
  void store_calibration(RunId run_id, const CalibrationRecord& calibration) override;
  void store_crosscheck(RunId run_id, const CrosscheckRecord& crosscheck) override;
  void set_diagnosis(RunId run_id, const std::string& diagnosis_json) override;
  std::vector<RunId> mark_interrupted_runs(TimestampMs now_ms) override;
  void promote(RunId run_id, const std::string& by, const std::string& reason,
               TimestampMs at_ms) override;

  std::vector<RunRecord> history(const std::string& serial, std::size_t limit = 0) const override;
  std::size_t run_count(const std::string& serial) const override;
  std::vector<RunRecord> recent_runs(std::size_t limit) const override;
  std::size_t total_run_count() const override;
  std::vector<RunRecord> station_runs(const std::string& station,
                                      const std::optional<std::string>& serial,
                                      std::size_t limit) const override;
  std::size_t station_run_count(const std::string& station,
                                const std::optional<std::string>& serial) const override;
  RunDetails show(RunId run_id) const override;
  ActiveCalibration active_params(const std::string& serial) const override;
  void export_rows(const ExportFilter& filter,
                   const std::function<void(const ExportRow&)>& sink) const override;
  std::vector<RunRecord> runs_with_archive_sha256(const std::string& sha256) const override;
  std::vector<RunRecord> runs_in_state(const std::vector<RunState>& states) const override;

  /// The stations with runs in the store, and how many each (ascending station id).
  std::vector<std::pair<std::string, std::size_t>> stations() const;
  const FleetTarget& target() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace imucal::db::fleet
