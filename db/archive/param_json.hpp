#pragma once
// The calibration parameter set as JSON (ARCHITECTURE §3) — the one schema for truth, estimates and
// DB:
//   {"accel_bias_mps2":[3], "accel_M":[[3],[3],[3]],
//    "gyro_bias_radps":[3], "gyro_M":[[3],[3],[3]],
//    "table_misalignment_rad":[3],
//    "sigma": {same five keys, 1-σ}}                     ("sigma" optional)
// SI units; matrices as 3 rows. Doubles are written in shortest round-trip form (bit-exact).
#include <nlohmann/json.hpp>
#include <string>

#include "calib/core/param_set.hpp"

namespace imucal::db::archive {

/// The five schema keys, in the order they are written.
const char* const kParamSetKeys[5] = {"accel_bias_mps2", "accel_M", "gyro_bias_radps", "gyro_M",
                                      "table_misalignment_rad"};

/// ParamSet (and optional 1-σ set) to JSON. ArchiveError (origin "<param set>") on NaN/Inf, which
/// JSON cannot carry, or on a negative sigma.
nlohmann::json param_set_to_json(const calib::core::ParamSet& params,
                                 const calib::core::ParamSet* sigma = nullptr);

/// JSON to ParamSet. Strict: all five keys required, unknown keys rejected, exact shapes, numbers
/// only, finite. Errors name `origin` and the field path, e.g. "run7/truth.json: field
/// 'accel_M[1][2]': expected a number, got string". If sigma_out is non-null the "sigma" object is
/// required (negative entries rejected) and stored there; if null, a present "sigma" is still
/// validated but discarded. An optional "source" object at the root (where the set came from:
/// `stationctl params` names its run there, issue #19) is allowed and not read.
calib::core::ParamSet param_set_from_json(const nlohmann::json& j, const std::string& origin,
                                          calib::core::ParamSet* sigma_out = nullptr);

/// Parse JSON text; a syntax error becomes ArchiveError("<origin>:<line>: <message>").
nlohmann::json parse_json_text(const std::string& text, const std::string& origin);

/// Read a parameter-set JSON file (see param_set_from_json for sigma_out).
calib::core::ParamSet read_param_file(const std::string& path,
                                      calib::core::ParamSet* sigma_out = nullptr);
/// Write a parameter-set JSON file (pretty-printed, durable; replaces an existing file atomically).
void write_param_file(const std::string& path, const calib::core::ParamSet& params,
                      const calib::core::ParamSet* sigma = nullptr);

}  // namespace imucal::db::archive
