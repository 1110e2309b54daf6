#include "db/archive/import_plausibility.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include "calib/core/conventions.hpp"
#include "calib/core/earth.hpp"

namespace imucal::db::archive {

namespace {

constexpr double kMinRate_hz = 1.0, kMaxRate_hz = 1e5;
/// |f| at rest within a factor 2 of gravity: a unit read with its nominal values only may be tens
/// of per cent off (IMU-TK's Xsens unit: 12.6 m/s², its zero offsets), a unit mix-up is a factor
/// 9.8 or more off. A mix-up is named when |f| is within 35 % of its factor.
constexpr double kPlausibleFactor = 2.0;
constexpr double kMixUpTolerance = 0.35;
constexpr double kMaxGyroRate_radps = 2000.0 * kDegToRad;  ///< beyond any gyro's full scale

std::string rounded(double v, int digits = 3) {
  char buf[48];
  std::snprintf(buf, sizeof buf, "%.*g", digits, v);
  return buf;
}

/// One second of the recording (fewer samples when the whole recording is shorter): its mean
/// specific force and rate, and how much the specific force varies in it.
struct Window {
  Eigen::Vector3d f_mean = Eigen::Vector3d::Zero(), w_mean = Eigen::Vector3d::Zero();
  double norm_spread = 0.0;  ///< RMS of |f| about its mean, relative to that mean
  double f_spread = 0.0;     ///< RMS of f about its mean vector, m/s²
  bool full = false;         ///< a whole second
};

/// The recording in one-second windows, read once for every check that looks for stillness.
std::vector<Window> one_second_windows(const RawRecording& rec) {
  const std::size_t n = rec.imu.size();
  const std::size_t w =
      std::max<std::size_t>(2, static_cast<std::size_t>(std::lround(rec.rate_hz)));
  std::vector<Window> out;
  for (std::size_t start = 0; start + w <= n || start == 0; start += w) {
    const std::size_t end = std::min(n, start + w);
    Window win;
    double s = 0.0, ss = 0.0;
    for (std::size_t k = start; k < end; ++k) {
      const Eigen::Vector3d f = rec.imu[k].dv_mps / rec.imu[k].dt_s;
      win.f_mean += f;
      win.w_mean += rec.imu[k].dtheta_rad / rec.imu[k].dt_s;
      s += f.norm();
      ss += f.squaredNorm();
    }
    const double m = static_cast<double>(end - start);
    win.f_mean /= m;
    win.w_mean /= m;
    const double norm_mean = s / m;
    win.norm_spread = std::sqrt(std::max(0.0, ss / m - norm_mean * norm_mean)) /
                      std::max(norm_mean, std::numeric_limits<double>::min());
    win.f_spread = std::sqrt(std::max(0.0, ss / m - win.f_mean.squaredNorm()));
    win.full = end - start == w;
    out.push_back(win);
    if (end == n) break;
  }
  return out;
}

/// |mean f| over the window whose |f| varies least (relative to its mean).
double stillest_specific_force(const std::vector<Window>& windows) {
  double best_spread = std::numeric_limits<double>::infinity(), best_norm = 0.0;
  for (const Window& w : windows)
    if (w.norm_spread < best_spread) {
      best_spread = w.norm_spread;
      best_norm = w.f_mean.norm();
    }
  return best_norm;
}

/// The rate check: a finding, or "".
std::string rate_finding(double rate_hz) {
  if (rate_hz >= kMinRate_hz && rate_hz <= kMaxRate_hz) return "";
  const std::string finding =
      "the time stamps give " + rounded(rate_hz) + " Hz, no IMU's rate (1 Hz to 100 kHz)";
  // Stamps read in a unit 10^3, 10^6 or 10^9 off: what they would give, and the likely mix-up.
  const std::pair<double, const char*> factors[] = {
      {1e3, "ms read as s?"},  {1e6, "us read as s?"},  {1e9, "ns read as s?"},
      {1e-3, "s read as ms?"}, {1e-6, "s read as us?"}, {1e-9, "s read as ns?"}};
  for (const auto& [factor, mix_up] : factors) {
    const double r = rate_hz * factor;
    if (r >= 10.0 && r <= 1e4)
      return finding + ": " + mix_up + " They would give " + rounded(r) +
             " Hz — give --time-unit (s, ms, us, ns)";
  }
  return finding + " — check the time column and --time-unit";
}

/// The accelerometer check at the stillest second: a finding, or "".
std::string force_finding(double f_mps2, double gravity_mps2, double rate_hz) {
  const double ratio = f_mps2 / gravity_mps2;
  if (ratio >= 1.0 / kPlausibleFactor && ratio <= kPlausibleFactor) return "";
  const std::string what = "|f| over the stillest second is " + rounded(f_mps2, 4) +
                           " m/s² against the site's gravity " + rounded(gravity_mps2, 6) + " m/s²";
  if (std::abs(ratio * kStandardGravity_mps2 - 1.0) <= kMixUpTolerance)
    return what + ": the accelerometers read g, not m/s² — give --accel-scale 9.80665";
  if (std::abs(ratio * kStandardGravity_mps2 / 1000.0 - 1.0) <= kMixUpTolerance)
    return what + ": the accelerometers read mg — give --accel-scale 0.00980665";
  if (std::abs(ratio * rate_hz - 1.0) <= kMixUpTolerance)
    return what +
           ": the values are increments per sample (|f| × period ≈ gravity) — give "
           "--quantity increments";
  if (ratio > 50.0)
    return what +
           ": raw counts without their scale — give --accel-scale (m/s² per count, "
           "e.g. 9.80665/16384 for a ±2 g 16-bit unit) and --accel-offset";
  return what + ": check --accel-scale and --accel-offset";
}

/// The gyro check over the whole recording: a finding, or "".
std::string rate_of_turn_finding(const RawRecording& rec) {
  std::vector<double> w;
  w.reserve(rec.imu.size());
  for (const auto& s : rec.imu) w.push_back(s.dtheta_rad.norm() / s.dt_s);
  // The 99.9th percentile: a few corrupt samples are the calibration's matter, not the units'.
  const std::size_t i = std::min(w.size() - 1, w.size() * 999 / 1000);
  std::nth_element(w.begin(), w.begin() + static_cast<long>(i), w.end());
  const double w_max = w[i];
  if (w_max <= kMaxGyroRate_radps) return "";
  const std::string what = "the gyros turn at up to " + rounded(w_max / kDegToRad, 4) +
                           " °/s, beyond any gyro's range (" +
                           rounded(kMaxGyroRate_radps / kDegToRad, 4) + " °/s)";
  if (w_max * kDegToRad <= kMaxGyroRate_radps)
    return what +
           ": deg/s read as rad/s — give --gyro-scale 0.0174533 (or the counts' scale in "
           "rad/s per count)";
  return what +
         ": raw counts without their scale — give --gyro-scale (rad/s per count) and "
         "--gyro-offset";
}

/// The smallest mean rate (norm) over the whole one-second windows whose f is as still as the
/// stillest one's (within twice its spread): every rest shows the gyros' bias, so the smallest is
/// a rest's even where a constant-rate turn about the vertical keeps f as still as a rest.
double rest_rate_radps(const std::vector<Window>& windows) {
  double stillest = std::numeric_limits<double>::infinity();
  for (const Window& w : windows)
    if (w.full) stillest = std::min(stillest, w.f_spread);
  double smallest = std::numeric_limits<double>::infinity();
  for (const Window& w : windows)
    if (w.full && w.f_spread <= 2.0 * stillest) smallest = std::min(smallest, w.w_mean.norm());
  return std::isfinite(smallest) ? smallest : 0.0;
}

/// The rest-rate check: a finding, or "". The limit: three times the grade's bias envelope on
/// every axis at once, plus twice the Earth's rate.
std::string rest_rate_finding(const std::vector<Window>& windows, calib::core::Grade grade) {
  const double bias = calib::core::grade_prior(grade).gyro_bias_radps;
  const double limit = 3.0 * std::sqrt(3.0) * bias + 2.0 * calib::core::wgs84::kEarthRate_radps;
  const double w = rest_rate_radps(windows);
  if (!(w > limit)) return "";
  const std::string what = "the gyros read " + rounded(w / kDegToRad, 3) +
                           " °/s where the unit is stillest, beyond what a " +
                           calib::core::grade_name(grade) + " unit's bias may be (" +
                           rounded(limit / kDegToRad, 2) + " °/s with the Earth's rate)";
  const double mems_limit =
      3.0 * std::sqrt(3.0) * calib::core::grade_prior(calib::core::Grade::kMems).gyro_bias_radps;
  if (w * kDegToRad <= mems_limit)
    return what +
           ": deg/s read as rad/s? — give --gyro-scale 0.0174533; or a unit of another grade "
           "(--grade), or a zero not removed (--gyro-offset)";
  return what + ": a unit of another grade (--grade), or a zero not removed (--gyro-offset)";
}

}  // namespace

std::vector<std::string> implausible_reading(const RawRecording& rec, double gravity_mps2,
                                             calib::core::Grade grade) {
  std::vector<std::string> findings;
  if (rec.imu.size() < 2) return findings;
  const std::vector<Window> windows = one_second_windows(rec);
  for (const std::string& f :
       {rate_finding(rec.rate_hz),
        force_finding(stillest_specific_force(windows), gravity_mps2, rec.rate_hz),
        rate_of_turn_finding(rec), rest_rate_finding(windows, grade)})
    if (!f.empty()) findings.push_back(f);
  return findings;
}

}  // namespace imucal::db::archive
