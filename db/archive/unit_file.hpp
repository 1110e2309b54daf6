#pragma once
// Unit files (TOML, human units) -> calib::effects::UnitModel, and truth.json (SI) of simulated
// runs. Keys and units are listed in db/archive/FORMAT.md. Missing keys mean zero (a perfect
// sensor, no effect), except [noise] whose missing keys take the calib::core::NoiseModel{}
// defaults. Unknown keys are rejected with their line.
#include <string>
#include <vector>

#include "calib/core/param_set.hpp"
#include "calib/effects/unit_model.hpp"

namespace imucal::db::archive {

calib::effects::UnitModel read_unit_file(const std::string& path);
/// Parse unit-file text; `origin` names it in errors.
calib::effects::UnitModel parse_unit_file(const std::string& text, const std::string& origin);
/// Unit-file text for a unit; parse_unit_file(unit_file_text(u)) == u bit-exactly wherever the
/// human-unit conversion can reach the SI value (otherwise within an ulp).
std::string unit_file_text(const calib::effects::UnitModel& unit);
void write_unit_file(const std::string& path, const calib::effects::UnitModel& unit);

/// What a simulated run's truth.json holds: the injected parameters, every injected effect with its
/// values (the catalogue of calib/effects/catalogue.hpp) and the noise model, all SI.
struct Truth {
  calib::core::ParamSet params;
  calib::effects::Effects effects;
  calib::core::NoiseModel noise;
  /// false for a truth.json written before effect values were stored (a list of names): then
  /// `effects` is all zero and legacy_effect_names holds the names.
  bool effect_values_known = true;
  std::vector<std::string> legacy_effect_names;
  /// The injected effects' names, catalogue order.
  std::vector<std::string> effect_names() const {
    return effect_values_known ? effects.active_names() : legacy_effect_names;
  }
};

/// Truth from a unit model as simulated (params, active effect names, noise).
Truth truth_from_unit(const calib::effects::UnitModel& unit);

/// truth.json text: {"params": <param set JSON>, "effects": {"<effect>": {"<param>": SI value, ...},
/// ...} (active effects only, catalogue parameter names, shape parameters included), "noise": {...}}.
/// The reader also accepts the older "effects": [names] (values unknown).
std::string truth_json_text(const Truth& truth);
Truth parse_truth_json(const std::string& text, const std::string& origin);
void write_truth_json(const std::string& path, const Truth& truth);
Truth read_truth_json(const std::string& path);

}  // namespace imucal::db::archive
