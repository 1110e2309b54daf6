#pragma once
// The seam between the world and the studies that need runs of it. The diagnosis' detectability
// and its blind validation draw runs of one sequence by one unit with chosen effects injected;
// they take them from a RunSource and never include a simulator (ARCHITECTURE §2). calib/sim/
// provides the truth simulator's (truth_run_source); any other simulator of the same table may
// serve.
#include <cstdint>
#include <functional>

#include "calib/core/calibration_input.hpp"
#include "calib/effects/catalogue.hpp"

namespace imucal::calib::effects {
using namespace calib::core;

/// A run of the source's sequence by its unit with `effects` injected (an empty Effects: none),
/// noise drawn from `seed`, or the exact increments when `noise` is false — as the methods consume
/// it, with the unit's declared noise model. Must be callable from several threads at once.
using RunSource =
    std::function<CalibrationInput(const Effects& effects, uint64_t seed, bool noise)>;

}  // namespace imucal::calib::effects
