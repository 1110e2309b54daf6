#include "db/fleet/fleet_codec.hpp"

#include "db/archive/archive_error.hpp"
#include "db/archive/param_json.hpp"

namespace imucal::db::fleet {
using namespace db::history;

using nlohmann::json;

namespace {

json parse(const std::string& text, const std::string& origin) {
  try {
    return json::parse(text);
  } catch (const json::exception& e) {
    throw Corrupt(origin + ": stored JSON is invalid: " + e.what());
  }
}

}  // namespace

json params_json(const calib::core::ParamSet& p) { return db::archive::param_set_to_json(p); }

calib::core::ParamSet params_from_json(const std::string& text, const std::string& origin) {
  try {
    return db::archive::param_set_from_json(parse(text, origin), origin);
  } catch (const db::archive::ArchiveError& e) {
    throw Corrupt(std::string("stored value is invalid: ") + e.what());
  }
}

json metrics_json(const StoredMetrics& m) {
  const Eigen::Vector3d& t = m.body_misalignment_theta_bp_rad;
  return {{"orientation_rmse_mdeg", m.orientation_rmse_mdeg},
          {"accel_rmse_ug", m.accel_rmse_ug},
          {"heading_offset_gamma_np_rad", m.heading_offset_gamma_np_rad},
          {"body_misalignment_theta_bp_rad", {t.x(), t.y(), t.z()}}};
}

StoredMetrics metrics_from_json(const std::string& text, const std::string& origin) {
  const json j = parse(text, origin);
  try {
    StoredMetrics m;
    m.orientation_rmse_mdeg = j.at("orientation_rmse_mdeg").get<double>();
    m.accel_rmse_ug = j.at("accel_rmse_ug").get<double>();
    m.heading_offset_gamma_np_rad = j.at("heading_offset_gamma_np_rad").get<double>();
    const json& t = j.at("body_misalignment_theta_bp_rad");
    m.body_misalignment_theta_bp_rad = {t.at(0).get<double>(), t.at(1).get<double>(),
                                        t.at(2).get<double>()};
    return m;
  } catch (const json::exception& e) {
    throw Corrupt(origin + ": stored metrics are invalid: " + e.what());
  }
}

std::vector<std::string> strings_from_json(const std::string& text, const std::string& origin) {
  try {
    return parse(text, origin).get<std::vector<std::string>>();
  } catch (const json::exception& e) {
    throw Corrupt(origin + ": not an array of strings: " + e.what());
  }
}

std::vector<RunReason> reasons_from_json(const std::string& text, const std::string& origin) {
  std::vector<RunReason> out;
  try {
    for (const json& e : parse(text, origin))
      out.push_back({e.at("source").get<std::string>(), e.at("text").get<std::string>()});
  } catch (const json::exception& e) {
    throw Corrupt(origin + ": stored reasons are invalid: " + e.what());
  }
  return out;
}

std::vector<calib::checks::CrossCheckFailure> failures_from_json(const std::string& text,
                                                                 const std::string& origin) {
  std::vector<calib::checks::CrossCheckFailure> out;
  try {
    for (const json& f : parse(text, origin))
      out.push_back({f.at("term").get<std::string>(), f.at("detail").get<std::string>()});
  } catch (const json::exception& e) {
    throw Corrupt(origin + ": stored cross-check failures are invalid: " + e.what());
  }
  return out;
}

}  // namespace imucal::db::fleet
