#pragma once
// Fast reading of the parameter-set text the history database stores (params_json, sigma_json):
// the compact JSON dump of the five-key parameter set (ARCHITECTURE §3), e.g.
//   {"accel_M":[[1e-07,...],[...],[...]],"accel_bias_mps2":[...],"gyro_M":...,...}
// An export reads two of these per row, 400 000 for 100 000 runs, and a general JSON parser spent
// three quarters of the export's time building trees for them. This reader accepts exactly that
// shape (the five keys once each, in any order, no whitespace, JSON numbers) and nothing else: any
// other text makes it return false, and the caller parses it strictly for a field-named error.
#include <string_view>

#include "calib/core/param_set.hpp"

namespace imucal::db::history {

/// True and `out` filled if `text` is a compact five-key parameter set of finite numbers (and,
/// with `non_negative`, none below zero: a 1-σ set); false otherwise (`out` then unspecified).
bool read_compact_param_set(std::string_view text, bool non_negative, calib::core::ParamSet& out);

}  // namespace imucal::db::history
