#include "station/run/recovery.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "db/archive/run_archive.hpp"
#include "drivers/turntable/turntable_client.hpp"
#include "station/run/archive_writer.hpp"
#include "station/run/capture_stats.hpp"
#include "station/run/end_note.hpp"
#include "station/run/run_controller.hpp"

namespace imucal::station::run {
using namespace station::config;

namespace fs = std::filesystem;

namespace {

/// The [capture] counters of a (recovered) run.toml as JSON text, "" if unreadable or absent.
std::string capture_json_of(const std::string& dir) {
  try {
    const std::string path = (fs::path(dir) / "run.toml").string();
    std::ifstream in(path);
    std::ostringstream ss;
    ss << in.rdbuf();
    const db::archive::RunInfo info = db::archive::parse_run_info(ss.str(), path);
    if (!info.capture) return "";
    return to_json(capture_stats_from_info(*info.capture)).dump();
  } catch (const std::exception& e) {
    spdlog::warn("recovery: {}: {}", dir, e.what());
    return "";
  }
}

void stop_table(const StationConfig& config, RecoveryReport& report) {
  drivers::turntable::TurntableClientConfig tc = config.turntable;
  tc.stop_on_connect = true;  // connect() itself commands the safe stop
  // Do not hold up start-up for long: a table that is switched off is not an error.
  tc.reconnect_give_up = std::min(tc.reconnect_give_up, std::chrono::milliseconds(2000));
  try {
    drivers::turntable::TurntableClient client(tc);
    client.connect();
    client.close();
    report.table_reached = true;
    spdlog::info("recovery: table {} reached; safe stop commanded", tc.endpoint.to_string());
  } catch (const std::exception& e) {
    report.table_note = e.what();
    spdlog::warn("recovery: table not reachable, no stop commanded: {}", e.what());
  }
}

}  // namespace

RecoveryReport recover_at_startup(const StationConfig& config, db::history::Repository& repo,
                                  bool stop) {
  RecoveryReport report;
  if (stop) stop_table(config, report);

  for (const db::history::RunRecord& run : repo.runs_in_state(db::history::live_states())) {
    RecoveredRun r;
    r.run_id = run.run_id;
    r.found_in = run.state;
    const std::string dir = run.archive_path.empty()
                                ? run_archive_dir(config.data_dir, run.run_id, run.serial)
                                : run.archive_path;
    const std::string found = std::string("the daemon stopped while the run was ") +
                              db::history::to_string(run.state) +
                              " (found at start-up; not resumed)";
    db::history::RunCompletion c;
    c.state = db::history::RunState::kInterrupted;
    // The run ended while the database could not record it (disk full): its own end and reason.
    const std::string note_path = end_note_path(config.data_dir, run.run_id);
    const std::optional<EndNote> note = read_end_note(note_path);
    if (fs::exists(fs::path(dir) / "run.toml")) {
      try {
        r.rows_kept = recover_archive(dir, db::history::format_time_utc(db::history::now_ms()),
                                      decoder_options(slot_named(config, run.slot)));
        r.archive_sha256 = archive_digest(dir);
        r.archive_path = dir;
        r.reason = r.rows_kept == 0
                       ? found + "; archive " + dir +
                             " kept, but it holds no data rows yet: nothing to reprocess"
                       : found + "; archive " + dir + " kept with " + std::to_string(r.rows_kept) +
                             " rows, reprocess it to calibrate";
        c.capture_json = capture_json_of(dir);
      } catch (const std::exception& e) {
        r.archive_path = dir;
        r.reason = found + "; archive " + dir + " could not be recovered: " + e.what();
      }
      c.archive_path = dir;
      c.archive_sha256 = r.archive_sha256;
    } else {
      r.reason = found + "; it had no archive yet (stopped before the capture started)";
    }
    if (note) {
      c.state = note->state;
      c.verdict = note->verdict;
      r.reason = note->reason +
                 " (recorded at start-up from the run's end note: the database "
                 "could not take it then); " +
                 r.reason;
    }
    c.reason = r.reason;
    c.ended_at_ms = db::history::now_ms();
    repo.finish_run(run.run_id, c);
    remove_end_note(note_path);
    spdlog::warn("recovery: run {} ({}) {}: {}", run.run_id, run.serial,
                 db::history::to_string(c.state), r.reason);
    report.runs.push_back(std::move(r));
  }
  return report;
}

db::history::RunId highest_archived_run_id(const std::string& data_dir) {
  db::history::RunId highest = 0;
  std::error_code ec;
  for (const fs::directory_entry& e : fs::directory_iterator(fs::path(data_dir) / "runs", ec)) {
    // run_archive_dir's names: the run id, '-', the serial. Anything else is not a run archive.
    const std::string name = e.path().filename().string();
    const std::size_t dash = name.find('-');
    if (dash == 0 || dash == std::string::npos || !e.is_directory(ec)) continue;
    if (!std::all_of(name.begin(), name.begin() + static_cast<std::ptrdiff_t>(dash),
                     [](char c) { return c >= '0' && c <= '9'; }))
      continue;
    try {
      highest = std::max<db::history::RunId>(highest, std::stoll(name.substr(0, dash)));
    } catch (const std::out_of_range&) {
      continue;  // more digits than a run id has: not one of ours
    }
  }
  return highest;
}

db::history::RunId continue_run_ids_after_archives(const StationConfig& config,
                                                   db::history::SqliteRepository& repository) {
  const db::history::RunId archived = highest_archived_run_id(config.data_dir);
  const db::history::RunId issued = repository.highest_run_id_issued();
  if (archived <= issued || !repository.continue_run_ids_after(archived)) return 0;
  spdlog::warn(
      "history {} has numbered runs up to {} only, but {}/runs holds archives up to run {}: "
      "the database was replaced or restored from an older copy. New runs are numbered from {} "
      "so that no archive, and no copy in a fleet store, meets its id again",
      config.database, issued, config.data_dir, archived, archived + 1);
  return archived;
}

}  // namespace imucal::station::run
