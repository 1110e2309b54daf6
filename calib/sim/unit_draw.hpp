#pragma once
// A unit drawn from its grade's envelope (calib/core/unit_grade.hpp), for simulated runs of
// tactical and MEMS units (issue #21): gyro biases of half to all of the envelope on every axis
// (random signs), accelerometer biases and misalignments anywhere within it, gyro scales within
// 80 % of it and accelerometer scales within a third, the grade's noise. Navigation grade: the
// default unit of ARCHITECTURE §7 (default_unit()), as before grades existed.
#include <cstdint>

#include "calib/core/unit_grade.hpp"
#include "calib/sim/truth_sim.hpp"

namespace imucal::calib::sim {
using namespace calib::core;
using namespace calib::effects;

UnitModel draw_unit(Grade grade, uint64_t seed);

/// A unit of a production population (issue #25, simulated fleets): navigation grade with the
/// default unit's noise and every parameter drawn uniformly within ARCHITECTURE §7's sizes before
/// calibration — accelerometer bias ±100 µg, gyro bias ±0.02 °/h, scale factors ±500 ppm,
/// misalignments ±500 µrad — so units differ as a line's do; other grades as draw_unit. ς (the
/// table's) is left zero: a station sets its own.
UnitModel draw_production_unit(Grade grade, uint64_t seed);

}  // namespace imucal::calib::sim
