#include "calib/core/readable_number.hpp"

#include <cmath>
#include <cstdio>

namespace imucal::calib::core {

std::string seconds_text(double s) {
  char buf[48];
  if (std::isfinite(s) && std::fabs(s) >= 100.0)
    std::snprintf(buf, sizeof buf, "%.0f s", s);
  else
    std::snprintf(buf, sizeof buf, "%.3g s", s);
  return buf;
}

std::string instant_text(double t_s) {
  char buf[48];
  std::snprintf(buf, sizeof buf, "t = %.2f s", t_s);
  return buf;
}

}  // namespace imucal::calib::core
