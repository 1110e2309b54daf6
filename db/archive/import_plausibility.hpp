#pragma once
// Is an imported recording what its import options say it is (issue #48 item 5)? A recording read
// with a wrong unit imports cleanly and comes back from `imucal calibrate` as a motion problem
// ("no rest found"); here it is refused at import, naming the factor and the option that fixes it:
// - the stamps' rate against IMU rates (1 Hz to 100 kHz): ms read as s gives 0.1 Hz;
// - |f| over the recording's stillest second against the site's gravity (within a factor 2): g read
// as
//   m/s² gives 1.0, raw counts thousands, increments read as rates gravity × the period;
// - the gyros' largest rate against what any gyro measures (2 000 °/s): deg/s read as rad/s turns
//   a 90 °/s move into 5 157 °/s, raw counts tens of thousands;
// - the gyros' rate where the unit is still against what the grade's bias may be (plus the Earth's
//   rate): a 1 °/s MEMS offset read as rad/s is 57 °/s at rest though no move reaches 2 000 °/s,
//   and a MEMS unit imported as navigation grade shows its few °/s.
#include <string>
#include <vector>

#include "calib/core/unit_grade.hpp"
#include "db/archive/raw_recording.hpp"

namespace imucal::db::archive {

/// What cannot be right about `rec`, each finding with its likely cause and the option that fixes
/// it; empty when nothing is implausible.
/// `grade`: the unit's grade as imported (its bias envelope bounds the rest rate).
std::vector<std::string> implausible_reading(const RawRecording& rec, double gravity_mps2,
                                             calib::core::Grade grade);

}  // namespace imucal::db::archive
