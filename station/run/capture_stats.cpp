#include "station/run/capture_stats.hpp"

#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace imucal::station::run {

namespace {

using Member = uint64_t CaptureStats::*;

// The counters in run.toml order; names match db::archive::CaptureInfo::counters() (checked in
// counter_pairs()) so that the JSON, the database and the archive use one vocabulary.
const std::vector<std::pair<const char*, Member>>& counters() {
  static const std::vector<std::pair<const char*, Member>> list = {
      {"frames_received", &CaptureStats::frames_received},
      {"frames_logged", &CaptureStats::frames_logged},
      {"frames_foreign", &CaptureStats::frames_foreign},
      {"frames_error", &CaptureStats::frames_error},
      {"frames_malformed", &CaptureStats::frames_malformed},
      {"frames_duplicate", &CaptureStats::frames_duplicate},
      {"frames_out_of_order", &CaptureStats::frames_out_of_order},
      {"frames_discarded", &CaptureStats::frames_discarded},
      {"rx_overflow", &CaptureStats::rx_overflow},
      {"samples_decoded", &CaptureStats::samples_decoded},
      {"samples_lost", &CaptureStats::samples_lost},
      {"samples_corrupt", &CaptureStats::samples_corrupt},
      {"samples_incomplete", &CaptureStats::samples_incomplete},
      {"samples_late", &CaptureStats::samples_late},
      {"samples_filled", &CaptureStats::samples_filled},
      {"max_gap_samples", &CaptureStats::max_gap_samples},
      {"imu_resets", &CaptureStats::imu_resets},
      {"rows_written", &CaptureStats::rows_written},
      {"rest_samples", &CaptureStats::rest_samples},
  };
  return list;
}

// Pairs of (stats member, archive member) for the same name; throws if the two lists ever diverge.
const std::vector<std::pair<Member, uint64_t db::archive::CaptureInfo::*>>& counter_pairs() {
  static const std::vector<std::pair<Member, uint64_t db::archive::CaptureInfo::*>> pairs = [] {
    const auto& ours = counters();
    const auto& theirs = db::archive::CaptureInfo::counters();
    if (ours.size() != theirs.size())
      throw std::logic_error(
          "CaptureStats and db::archive::CaptureInfo counter lists differ in size");
    std::vector<std::pair<Member, uint64_t db::archive::CaptureInfo::*>> p;
    for (std::size_t i = 0; i < ours.size(); ++i) {
      if (std::string(ours[i].first) != theirs[i].first)
        throw std::logic_error(std::string("CaptureStats counter '") + ours[i].first +
                               "' does not match db::archive::CaptureInfo counter '" +
                               theirs[i].first + "'");
      p.emplace_back(ours[i].second, theirs[i].second);
    }
    return p;
  }();
  return pairs;
}

}  // namespace

bool operator==(const CaptureStats& a, const CaptureStats& b) {
  for (const auto& c : counters())
    if (a.*(c.second) != b.*(c.second)) return false;
  return true;
}

nlohmann::json to_json(const CaptureStats& stats) {
  nlohmann::json j = nlohmann::json::object();
  for (const auto& [name, member] : counters()) j[name] = stats.*member;
  return j;
}

CaptureStats capture_stats_from_json(const nlohmann::json& j) {
  auto fail = [](const std::string& field, const std::string& what) {
    throw std::invalid_argument(
        "capture stats: " + (field.empty() ? std::string() : "field '" + field + "': ") + what);
  };
  if (!j.is_object()) fail("", std::string("expected a JSON object, got ") + j.type_name());
  for (auto it = j.begin(); it != j.end(); ++it) {
    bool known = false;
    for (const auto& c : counters()) known = known || it.key() == c.first;
    if (!known) fail(it.key(), "unknown member");
  }
  CaptureStats s;
  for (const auto& [name, member] : counters()) {
    const auto it = j.find(name);
    if (it == j.end()) fail(name, "missing");
    if (it->is_number_unsigned()) {
      s.*member = it->get<uint64_t>();
    } else if (it->is_number_integer()) {  // signed storage (built in code, not parsed)
      const int64_t v = it->get<int64_t>();
      if (v < 0) fail(name, "must be >= 0, got " + it->dump());
      s.*member = static_cast<uint64_t>(v);
    } else {
      fail(name, std::string("expected a non-negative integer, got ") + it->type_name() + " " +
                     it->dump());
    }
  }
  return s;
}

db::archive::CaptureInfo to_capture_info(const CaptureStats& stats, bool complete) {
  db::archive::CaptureInfo ci;
  ci.complete = complete;
  for (const auto& [ours, theirs] : counter_pairs()) ci.*theirs = stats.*ours;
  return ci;
}

CaptureStats capture_stats_from_info(const db::archive::CaptureInfo& info) {
  CaptureStats s;
  for (const auto& [ours, theirs] : counter_pairs()) s.*ours = info.*theirs;
  return s;
}

void set_decoder_counters(CaptureStats& s, const drivers::imu::DecoderCounters& d) {
  s.frames_foreign = d.foreign_frames;
  s.frames_error = d.error_frames;
  s.frames_malformed = d.malformed_frames;
  s.frames_duplicate = d.duplicate_frames;
  s.frames_out_of_order = d.out_of_order_frames;
  s.frames_discarded = d.discarded_frames;
  s.samples_decoded = d.samples_decoded;
  s.samples_lost = d.samples_lost;
  s.samples_corrupt = d.samples_corrupt;
  s.samples_incomplete = d.samples_incomplete;
  s.samples_late = d.samples_late;
  s.imu_resets = d.imu_resets;
}

}  // namespace imucal::station::run
