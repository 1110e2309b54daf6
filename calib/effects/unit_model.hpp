#pragma once
// A unit as a simulator draws it and a unit file (db/archive) or truth.json describes it: its true
// calibration parameters, noise, unmodelled effects and grade. Plain data, shared by the world
// (calib/sim) and whoever reads or writes units, so that neither needs the other.
#include "calib/core/noise_model.hpp"
#include "calib/core/param_set.hpp"
#include "calib/core/unit_grade.hpp"
#include "calib/effects/catalogue.hpp"

namespace imucal::calib::effects {
using namespace calib::core;

struct UnitModel {
  ParamSet params;  ///< true calibration parameters (table_misalignment = the station's ς)
  NoiseModel noise;
  Effects effects;  ///< unmodelled physics (ARCHITECTURE §7); empty = none
  /// The product the unit is (calib/core/unit_grade.hpp): what a run of it states in [prior].
  Grade grade = Grade::kNavigation;
};

/// The default unit of ARCHITECTURE §7 (fixed, deterministic values within the stated sizes).
UnitModel default_unit();

}  // namespace imucal::calib::effects
