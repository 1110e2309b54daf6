#include "db/history/fleet_stats.hpp"

#include <algorithm>
#include <cmath>

#include "calib/core/param_set.hpp"
#include "db/history/serial_number.hpp"

namespace imucal::db::history {

namespace {

constexpr std::int64_t kDayMs = 86400000;
constexpr std::size_t kMaxStationBytes = 200;

/// Quantile p of sorted values by linear interpolation (type 7).
double quantile_sorted(const std::vector<double>& x, double p) {
  const double h = static_cast<double>(x.size() - 1) * p;
  const auto lo = static_cast<std::size_t>(std::floor(h));
  if (lo + 1 >= x.size()) return x.back();
  return x[lo] + (h - static_cast<double>(lo)) * (x[lo + 1] - x[lo]);
}

}  // namespace

int param_index(const std::string& name) {
  for (int i = 0; i < calib::core::ParamSet::kSize; ++i)
    if (calib::core::param_info(i).name == name) return i;
  throw InvalidInput("parameter \"" + name.substr(0, 80) +
                     "\" is unknown (expected a name of the parameter-set JSON such as "
                     "accel_bias_mps2[0], accel_M[0][1], gyro_bias_radps[2], gyro_M[2][2], "
                     "table_misalignment_rad[1])");
}

std::int64_t utc_day(TimestampMs t_ms) {
  return t_ms >= 0 ? t_ms / kDayMs : -((-t_ms + kDayMs - 1) / kDayMs);
}

ParamSummary summarize(std::vector<double>& values) {
  ParamSummary s;
  s.count = static_cast<std::int64_t>(values.size());
  if (values.empty()) return s;
  std::sort(values.begin(), values.end());
  double sum = 0;
  for (double v : values) sum += v;
  s.mean = sum / static_cast<double>(values.size());
  double ss = 0;  // two-pass: no cancellation for values far from zero
  for (double v : values) ss += (v - s.mean) * (v - s.mean);
  s.std_dev = values.size() > 1 ? std::sqrt(ss / static_cast<double>(values.size() - 1)) : 0.0;
  s.min = values.front();
  s.max = values.back();
  s.q1 = quantile_sorted(values, 0.25);
  s.median = quantile_sorted(values, 0.5);
  s.q3 = quantile_sorted(values, 0.75);
  return s;
}

void validate_filter(const FleetFilter& f) {
  if (f.since_ms && f.until_ms && *f.since_ms > *f.until_ms)
    throw InvalidInput("since " + format_time_utc(*f.since_ms) + " is after until " +
                       format_time_utc(*f.until_ms));
  if (f.serial) validate_serial(*f.serial);
  if (f.station) {
    if (f.station->size() > kMaxStationBytes)
      throw InvalidInput("station name longer than " + std::to_string(kMaxStationBytes) + " bytes");
    for (unsigned char c : *f.station)
      if (c < 0x20 || c == 0x7F) throw InvalidInput("station name has a control character");
  }
}

}  // namespace imucal::db::history
