#pragma once
// Numbers in messages a person reads (issue #50 item 5: "lasts 4.660000000000004 s"): rounded to
// what they mean, not the shortest form that reads back as the same double (that one is for files).
#include <string>

namespace imucal::calib::core {

/// A duration in seconds to three significant digits, whole seconds from 100 s on, with its unit:
/// "4.66 s", "0.05 s", "20 s", "1234 s".
std::string seconds_text(double s);

/// An instant on a run's time axis, to the hundredth of a second (a sample at 100 Hz) with its
/// unit: "t = 168.51 s".
std::string instant_text(double t_s);

}  // namespace imucal::calib::core
