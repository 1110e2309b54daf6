#pragma once
// `imucal crlb --sequence S --effects [--false-alarm P] [--json]`: for every effect of the
// catalogue, the smallest magnitude the sequence detects at the diagnosis' false-alarm rate per run
// P (default the station's, calib::diagnosis::kDefaultGapFalseAlarm) and whether the diagnosis can
// separate it from the calibration parameters and from the other effects
// (calib/diagnosis/effect_detectability.hpp); for an effect it cannot separate, the sequence change
// that would.
#include <string>

namespace imucal::tools::imucal {

int cmd_crlb_effects(const std::string& seq, const std::string& unit_path, double rate_hz,
                     double false_alarm, bool json);

}  // namespace imucal::tools::imucal
