#pragma once
// The simulated twin of a recorded run (ARCHITECTURE §8 step 1, "simulate the same trajectory with
// the calibrated model"): the increments a unit with exactly the calibrated parameters and the
// declared white noise would have delivered along the run's own reference attitudes (table or
// attitude log), on the run's own time axis. Its residual statistics are what the model predicts
// for this run; the diagnosis puts them beside the real ones (per segment and overall).
//
// Physics (conventions.hpp), written for any reference, including a station's encoder log that
// holds its last reading during moves: the attitude is exp([ς×]) C_bn_ref per sample; dθ_k is the
// exact rotation vector of C_bn(k-1)ᵀ exp([ω_ie_n dt×]) C_bn(k); dv_k = C_bn(k-1)ᵀ (f_n dt + ½ dt²
// ω_ie_n × f_n) with f_n = -g_n (the table does not translate); then eq. 18/23 with the calibrated
// parameters, ARW/VRW noise and the declared quantisation.
#include <cstdint>

#include "calib/core/param_set.hpp"
#include "calib/diagnosis/gap_model.hpp"

namespace imucal::calib::diagnosis {
using namespace calib::core;

DiagnosisInput simulated_twin(const DiagnosisInput& real, const ParamSet& calibrated,
                              uint64_t seed);

}  // namespace imucal::calib::diagnosis
