#pragma once
// The catalogue's sensor effects evaluated on recorded data, sample by sample: what the gap
// diagnosis subtracts from each increment of a move (calib/diagnosis/gap_model.hpp), and what a
// calibration removes from a run before it starts once a diagnosis has named and sized an effect
// (`imucal calibrate --compensate`: the gap "once that effect is modelled").
#include "calib/core/imu_error_model.hpp"
#include "calib/core/imu_increment.hpp"
#include "calib/core/param_set.hpp"
#include "calib/effects/catalogue.hpp"
#include "calib/effects/sensor_effects.hpp"

namespace imucal::calib::effects {
using namespace calib::core;

/// The effects' perturbation of sample k's increments at its own kinematics as the calibrated
/// error model sees them: f and ω from the sample's compensated increments, ω̇ by central
/// differences of the neighbours' raw rates, the interval's start from `t_first_s` (the start of
/// the run's first interval: the thermal warm-up's clock).
IncrementDelta sensor_effects_at(const ImuSeries& imu, size_t k, const ImuCompensator& comp,
                                 const Effects& fx, double t_first_s);

/// Removes the sensor effects `fx` from every increment of `imu`, evaluated with the calibration
/// `calibrated` (all from the data as given: the neighbours' rates are read before any is
/// changed). Throws std::invalid_argument if `fx` holds a table or site effect: those are not in
/// the unit's data and cannot be taken out of it.
void remove_sensor_effects(ImuSeries& imu, const Effects& fx, const ParamSet& calibrated);

/// The check remove_sensor_effects makes first (callers may make it before any other work).
void check_removable(const Effects& fx);

}  // namespace imucal::calib::effects
