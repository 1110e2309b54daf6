#include "db/archive/param_json.hpp"

#include <algorithm>
#include <cmath>

#include "db/archive/archive_error.hpp"
#include "db/archive/io_util.hpp"

namespace imucal::db::archive {

namespace {

using nlohmann::json;

const char* kind_name(const json& j) { return j.type_name(); }

json vec_to_json(const Eigen::Vector3d& v, const std::string& field) {
  json a = json::array();
  for (int i = 0; i < 3; ++i) {
    if (!std::isfinite(v(i)))
      throw ArchiveError::field_error("<param set>", field + "[" + std::to_string(i) + "]",
                                      "cannot write NaN or Inf to JSON");
    a.push_back(v(i));
  }
  return a;
}

json mat_to_json(const Eigen::Matrix3d& m, const std::string& field) {
  json a = json::array();
  for (int r = 0; r < 3; ++r)
    a.push_back(vec_to_json(m.row(r).transpose(), field + "[" + std::to_string(r) + "]"));
  return a;
}

json params_object(const calib::core::ParamSet& p, const std::string& prefix) {
  json o = json::object();
  o["accel_bias_mps2"] = vec_to_json(p.accel_bias_mps2, prefix + "accel_bias_mps2");
  o["accel_M"] = mat_to_json(p.accel_M, prefix + "accel_M");
  o["gyro_bias_radps"] = vec_to_json(p.gyro_bias_radps, prefix + "gyro_bias_radps");
  o["gyro_M"] = mat_to_json(p.gyro_M, prefix + "gyro_M");
  o["table_misalignment_rad"] =
      vec_to_json(p.table_misalignment_rad, prefix + "table_misalignment_rad");
  return o;
}

double number_from(const json& j, const std::string& origin, const std::string& field) {
  if (!j.is_number())
    throw ArchiveError::field_error(origin, field,
                                    std::string("expected a number, got ") + kind_name(j));
  const double v = j.get<double>();
  if (!std::isfinite(v)) throw ArchiveError::field_error(origin, field, "not a finite number");
  return v;
}

Eigen::Vector3d vec_from(const json& j, const std::string& origin, const std::string& field) {
  if (!j.is_array() || j.size() != 3)
    throw ArchiveError::field_error(
        origin, field,
        std::string("expected an array of 3 numbers, got ") +
            (j.is_array() ? "an array of " + std::to_string(j.size()) : std::string(kind_name(j))));
  Eigen::Vector3d v;
  for (int i = 0; i < 3; ++i)
    v(i) = number_from(j[static_cast<size_t>(i)], origin, field + "[" + std::to_string(i) + "]");
  return v;
}

Eigen::Matrix3d mat_from(const json& j, const std::string& origin, const std::string& field) {
  if (!j.is_array() || j.size() != 3)
    throw ArchiveError::field_error(
        origin, field,
        std::string("expected 3 rows of 3 numbers, got ") +
            (j.is_array() ? "an array of " + std::to_string(j.size()) : std::string(kind_name(j))));
  Eigen::Matrix3d m;
  for (int r = 0; r < 3; ++r)
    m.row(r) = vec_from(j[static_cast<size_t>(r)], origin, field + "[" + std::to_string(r) + "]")
                   .transpose();
  return m;
}

calib::core::ParamSet params_from_object(const json& j, const std::string& origin,
                                         const std::string& prefix, bool allow_sigma_key) {
  if (!j.is_object())
    throw ArchiveError::field_error(origin,
                                    prefix.empty() ? "<root>" : prefix.substr(0, prefix.size() - 1),
                                    std::string("expected a JSON object, got ") + kind_name(j));
  for (auto it = j.begin(); it != j.end(); ++it) {
    bool known = allow_sigma_key && (it.key() == "sigma" || it.key() == "source");
    for (const char* k : kParamSetKeys) known = known || it.key() == k;
    if (!known)
      throw ArchiveError::field_error(
          origin, prefix + it.key(),
          "unknown field (a parameter set has exactly accel_bias_mps2, "
          "accel_M, gyro_bias_radps, gyro_M, table_misalignment_rad" +
              std::string(allow_sigma_key ? " and optional sigma and source)" : ")"));
  }
  for (const char* k : kParamSetKeys)
    if (!j.contains(k)) throw ArchiveError::field_error(origin, prefix + k, "missing");
  calib::core::ParamSet p;
  p.accel_bias_mps2 = vec_from(j["accel_bias_mps2"], origin, prefix + "accel_bias_mps2");
  p.accel_M = mat_from(j["accel_M"], origin, prefix + "accel_M");
  p.gyro_bias_radps = vec_from(j["gyro_bias_radps"], origin, prefix + "gyro_bias_radps");
  p.gyro_M = mat_from(j["gyro_M"], origin, prefix + "gyro_M");
  p.table_misalignment_rad =
      vec_from(j["table_misalignment_rad"], origin, prefix + "table_misalignment_rad");
  return p;
}

}  // namespace

json param_set_to_json(const calib::core::ParamSet& params, const calib::core::ParamSet* sigma) {
  json o = params_object(params, "");
  if (sigma) {
    const calib::core::ParamVector s = sigma->to_vector();
    for (int i = 0; i < calib::core::ParamSet::kSize; ++i)
      if (s(i) < 0.0)
        throw ArchiveError::field_error("<param set>", "sigma." + calib::core::param_info(i).name,
                                        "a 1-sigma uncertainty cannot be negative");
    o["sigma"] = params_object(*sigma, "sigma.");
  }
  return o;
}

calib::core::ParamSet param_set_from_json(const json& j, const std::string& origin,
                                          calib::core::ParamSet* sigma_out) {
  calib::core::ParamSet p = params_from_object(j, origin, "", /*allow_sigma_key=*/true);
  if (j.contains("source") && !j["source"].is_object())
    throw ArchiveError::field_error(
        origin, "source", std::string("expected a JSON object, got ") + kind_name(j["source"]));
  if (j.contains("sigma")) {
    const calib::core::ParamSet s = params_from_object(j["sigma"], origin, "sigma.", false);
    const calib::core::ParamVector sv = s.to_vector();
    for (int i = 0; i < calib::core::ParamSet::kSize; ++i)
      if (sv(i) < 0.0)
        throw ArchiveError::field_error(origin, "sigma." + calib::core::param_info(i).name,
                                        "a 1-sigma uncertainty cannot be negative");
    if (sigma_out) *sigma_out = s;
  } else if (sigma_out) {
    throw ArchiveError::field_error(origin, "sigma", "missing (the caller requires uncertainties)");
  }
  return p;
}

json parse_json_text(const std::string& text, const std::string& origin) {
  try {
    return json::parse(text);
  } catch (const json::parse_error& e) {
    // e.byte is the 1-based position of the offending byte; report its line.
    const size_t upto = std::min(text.size(), e.byte > 0 ? static_cast<size_t>(e.byte - 1) : 0);
    const size_t line = 1 + static_cast<size_t>(std::count(
                                text.begin(), text.begin() + static_cast<long>(upto), '\n'));
    std::string what = e.what();
    const size_t colon = what.find(": ");
    throw ArchiveError(
        origin, line,
        "invalid JSON: " + (colon == std::string::npos ? what : what.substr(colon + 2)));
  } catch (const json::exception& e) {
    // E.g. out_of_range 406, a number beyond double's range (found by fuzzing): no position.
    std::string what = e.what();
    const size_t bracket = what.find("] ");
    throw ArchiveError(
        origin,
        "invalid JSON: " + (bracket == std::string::npos ? what : what.substr(bracket + 2)));
  }
}

calib::core::ParamSet read_param_file(const std::string& path, calib::core::ParamSet* sigma_out) {
  return param_set_from_json(parse_json_text(read_text_file(path), path), path, sigma_out);
}

void write_param_file(const std::string& path, const calib::core::ParamSet& params,
                      const calib::core::ParamSet* sigma) {
  write_file_atomic(path, param_set_to_json(params, sigma).dump(2) + "\n");
}

}  // namespace imucal::db::archive
