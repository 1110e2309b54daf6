#pragma once
// From a simulation to what the estimators and the diagnosis consume: the table reference from
// the simulated encoder angles, and the truth simulator as a RunSource. The bridges from the world
// (the simulator) to the estimate side, kept here so that nothing there includes the simulator.
#include "calib/core/calibration_input.hpp"
#include "calib/core/table_model.hpp"
#include "calib/core/unit_grade.hpp"
#include "calib/effects/run_source.hpp"
#include "calib/sim/field_sim.hpp"
#include "calib/sim/truth_sim.hpp"
#include "sequences/motion_profile.hpp"

namespace imucal::calib::sim {
using namespace calib::core;
using namespace calib::effects;

/// Build a CalibrationInput from a simulation (the table reference from encoder angles).
CalibrationInput input_from_simulation(const SimResult& sim, const TableGeometry& geometry,
                                       const Site& site, const NoiseModel& noise);

/// The truth simulator as a RunSource: runs of `profile` on the table `geometry` at `site` by
/// `unit` (its own effects replaced by the ones asked for) at `rate_hz`, the reference from the
/// simulated encoder angles and the unit's declared noise model. Keeps its own copy of everything.
RunSource truth_run_source(const sequences::MotionProfile& profile, const TableGeometry& geometry,
                           const Site& site, const UnitModel& unit, double rate_hz);

/// The field simulator as a RunSource (table-free runs, calib/sim/field_sim.hpp): `options` with
/// the seed and noise of each call, the rests found as `imucal calibrate` finds them for `grade`.
RunSource field_run_source(const sequences::MotionProfile& profile, const Site& site,
                           const UnitModel& unit, const FieldSimOptions& options,
                           Grade grade = Grade::kNavigation);

}  // namespace imucal::calib::sim
