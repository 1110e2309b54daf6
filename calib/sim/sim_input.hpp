#pragma once
// From a simulation to what the estimators consume: the table reference from the simulated
// encoder angles. The one bridge from the world (the simulator) to the estimate side, kept here so
// that calibration_input.hpp never includes the simulator.
#include "calib/core/calibration_input.hpp"
#include "calib/core/table_model.hpp"
#include "calib/sim/truth_sim.hpp"

namespace imucal::calib {

/// Build a CalibrationInput from a simulation (the table reference from encoder angles).
CalibrationInput input_from_simulation(const SimResult& sim, const TableGeometry& geometry,
                                       const Site& site, const NoiseModel& noise);

}  // namespace imucal::calib
