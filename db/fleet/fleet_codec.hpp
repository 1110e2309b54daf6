#pragma once
// The jsonb forms of a calibration's parts in the fleet store, and their inverse. Values: the
// export's forms (db/history/export.hpp); parameter sets: the five keys of ARCHITECTURE §3, without
// sigma.
#include <nlohmann/json.hpp>
#include <string>

#include "db/history/repository.hpp"

namespace imucal::db::fleet {
using namespace db::history;

nlohmann::json params_json(const calib::core::ParamSet& p);
calib::core::ParamSet params_from_json(const std::string& text, const std::string& origin);
nlohmann::json metrics_json(const StoredMetrics& m);
StoredMetrics metrics_from_json(const std::string& text, const std::string& origin);
std::vector<std::string> strings_from_json(const std::string& text, const std::string& origin);
std::vector<RunReason> reasons_from_json(const std::string& text, const std::string& origin);
std::vector<calib::checks::CrossCheckFailure> failures_from_json(const std::string& text,
                                                                 const std::string& origin);

}  // namespace imucal::db::fleet
