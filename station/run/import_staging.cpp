#include "station/run/import_staging.hpp"

#include <stdlib.h>

#include <filesystem>
#include <system_error>

#include "station/run/archive_writer.hpp"

namespace imucal::station::run {

namespace fs = std::filesystem;

namespace {

/// A run.toml time as UTC ms, or nullopt when absent or not a form db::history::parse_time_utc
/// reads.
std::optional<db::history::TimestampMs> parse_recorded(const std::string& iso) {
  if (iso.empty()) return std::nullopt;
  try {
    return db::history::parse_time_utc(iso);
  } catch (const db::history::InvalidInput&) {
    return std::nullopt;
  }
}

}  // namespace

RecordedTimes recorded_times(const db::archive::RunArchive& ar,
                             db::history::TimestampMs import_ms) {
  RecordedTimes t;
  const auto start = parse_recorded(ar.info.start_time);
  t.recorded = start.has_value();
  t.started_at_ms = start.value_or(import_ms);
  const auto end = parse_recorded(ar.info.end_time);
  t.ended_at_ms = end && *end > t.started_at_ms
                      ? *end
                      : t.started_at_ms + static_cast<db::history::TimestampMs>(
                                              db::archive::data_span_s(ar) * 1000.0 + 0.5);
  return t;
}

std::string import_origin(const std::string& dir, db::history::TimestampMs import_ms,
                          const RecordedTimes& times) {
  std::string s = "imported from " + dir + " on " + db::history::format_time_utc(import_ms);
  if (!times.recorded) s += " (run.toml has no start_time: the import time stands in)";
  return s;
}

StagedImport::StagedImport(const std::string& source_dir, const db::archive::RunArchive& ar,
                           const std::string& runs_dir) {
  fs::create_directories(runs_dir);
  std::string templ = (fs::path(runs_dir) / ".import-XXXXXX").string();
  if (!::mkdtemp(templ.data()))
    throw std::runtime_error("cannot create a directory in " + runs_dir + ": " +
                             std::generic_category().message(errno));
  staged_ = templ;
  try {
    source_sha256_ = archive_digest(source_dir);
    // write_archive wants to create its directory itself (atomically): hand it a fresh name.
    fs::remove(staged_);
    db::archive::write_archive(staged_, ar);
    copy_sha256_ = archive_digest(staged_);
  } catch (...) {
    std::error_code ec;
    fs::remove_all(staged_, ec);
    staged_.clear();
    throw;
  }
}

StagedImport::~StagedImport() {
  if (staged_.empty()) return;
  std::error_code ec;
  fs::remove_all(staged_, ec);
}

void StagedImport::move_to(const std::string& dest) {
  std::error_code ec;
  fs::rename(staged_, dest, ec);
  if (ec) throw std::runtime_error("cannot move " + staged_ + " to " + dest + ": " + ec.message());
  staged_.clear();
}

std::optional<std::string> duplicate_import(const db::history::Repository& repo,
                                            const StagedImport& staged) {
  for (const std::string& sha : {staged.source_sha256(), staged.copy_sha256()}) {
    const auto runs = repo.runs_with_archive_sha256(sha);
    if (runs.empty()) continue;
    const db::history::RunRecord& r = runs.front();
    std::string where = r.origin.empty() ? "recorded at this station" : r.origin;
    return "this archive (SHA-256 " + sha.substr(0, 16) + "...) is already stored as run " +
           std::to_string(r.run_id) + " of " + r.serial + " (" + db::history::to_string(r.state) +
           ", " + where + "); not imported again — `stationctl show " + std::to_string(r.run_id) +
           "` shows it";
  }
  return std::nullopt;
}

}  // namespace imucal::station::run
