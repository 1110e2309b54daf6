#pragma once
// Field-by-field comparison of a run as a station's SQLite holds it and as the fleet store holds it
// (issue #24): every field of RunDetails, with the ids that differ by construction (the store's own
// run id, and the references to other runs) replaced by the UUIDs of the runs they name.
#include <map>
#include <nlohmann/json.hpp>
#include <string>

#include "db/history/export.hpp"
#include "db/history/repository.hpp"

namespace imucal::test_support {

/// `uuid_of`: run id → UUID within the same database (SQLite or fleet).
inline nlohmann::json comparable_run(const db::history::RunDetails& d,
                                     const std::map<db::history::RunId, std::string>& uuid_of) {
  nlohmann::json j = db::history::run_details_json(d);
  auto uuid = [&](const std::optional<db::history::RunId>& id) -> nlohmann::json {
    if (!id) return nullptr;
    const auto it = uuid_of.find(*id);
    return it == uuid_of.end() ? nlohmann::json("unknown run " + std::to_string(*id))
                               : nlohmann::json(it->second);
  };
  j["run"]["run_id"] = d.run.uuid;
  j["run"]["reprocessed_from"] = uuid(d.run.reprocessed_from);
  j["run"]["table_run"] = uuid(d.run.table_run_id);
  j["run"]["revision"] = d.run.revision;
  j["run"]["capture_json_text"] = d.run.capture_json;
  j["run"]["diagnosis_json_text"] = d.run.diagnosis_json;
  j["run"]["promoted_at_ms"] =
      d.run.promoted_at_ms ? nlohmann::json(*d.run.promoted_at_ms) : nullptr;
  return j;
}

}  // namespace imucal::test_support
