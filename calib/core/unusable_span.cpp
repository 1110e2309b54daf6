#include "calib/core/unusable_span.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <optional>

#include "calib/core/conventions.hpp"

namespace imucal::calib::core {

namespace {

const char* const kChannel[6] = {"gyro x", "gyro y", "gyro z", "accel x", "accel y", "accel z"};

double channel(const ImuIncrement& s, int c) { return c < 3 ? s.dtheta_rad(c) : s.dv_mps(c - 3); }

}  // namespace

double median_interval_s(const ImuSeries& imu) {
  std::vector<double> dt;
  dt.reserve(imu.size());
  for (size_t k = 1; k < imu.size(); ++k) dt.push_back(imu[k].dt_s);
  if (dt.empty()) return imu.empty() ? 0.0 : imu.front().dt_s;
  std::nth_element(dt.begin(), dt.begin() + static_cast<std::ptrdiff_t>(dt.size() / 2), dt.end());
  return dt[dt.size() / 2];
}

namespace {

/// The plateaus of one channel at its extreme in one direction (sign +1: the largest value, -1:
/// the smallest), when that extreme is beyond `floor` (an increment).
void clipped_plateaus(const ImuSeries& imu, int c, int sign, double floor, double to_human,
                      const char* unit, std::vector<UnusableSpan>& out) {
  double extreme = 0.0;
  for (const ImuIncrement& s : imu) extreme = std::max(extreme, sign * channel(s, c));
  if (!(extreme > floor)) return;
  for (size_t k = 0; k < imu.size();) {
    if (sign * channel(imu[k], c) != extreme) {
      ++k;
      continue;
    }
    size_t end = k + 1;
    while (end < imu.size() && sign * channel(imu[end], c) == extreme) ++end;
    if (end - k >= 2) {
      char buf[160];
      std::snprintf(buf, sizeof buf, "%s clipped at %.4g %s (%zu samples)", kChannel[c],
                    sign * extreme * to_human, unit, end - k);
      out.push_back({k, end, buf});
    }
    k = end;
  }
}

}  // namespace

std::vector<UnusableSpan> find_clipped_spans(const ImuSeries& imu) {
  const double g_mps2 = kStandardGravity_mps2;
  std::vector<UnusableSpan> out;
  const double dt_s = median_interval_s(imu);
  if (!(dt_s > 0.0)) return out;
  for (int c = 0; c < 6; ++c) {
    const bool gyro = c < 3;
    const double floor =
        gyro ? kMinGyroRange_degps * kDegToRad * dt_s : kMinAccelRange_g * g_mps2 * dt_s;
    const double to_human = gyro ? 1.0 / (kDegToRad * dt_s) : 1.0 / (g_mps2 * dt_s);
    for (int sign : {+1, -1})
      clipped_plateaus(imu, c, sign, floor, to_human, gyro ? "°/s" : "g", out);
  }
  return out;
}

std::vector<UnusableSpan> find_time_gaps(const ImuSeries& imu) {
  std::vector<UnusableSpan> out;
  const double median = median_interval_s(imu);
  if (!(median > 0.0)) return out;
  for (size_t k = 1; k < imu.size(); ++k) {
    const double dt = imu[k].dt_s;
    if (!(dt > 1.5 * median)) continue;
    const long missing = std::max(1L, std::lround(dt / median) - 1);
    char buf[160];
    std::snprintf(buf, sizeof buf, "%ld sample%s missing (%.4g s without data before t = %.2f s)",
                  missing, missing == 1 ? "" : "s", dt - median, imu[k].t_s);
    out.push_back({k, k + 1, buf});
  }
  return out;
}

std::vector<UnusableSpan> find_splices(const ImuSeries& imu) {
  std::vector<UnusableSpan> out;
  const double dt_s = median_interval_s(imu);
  if (!(dt_s > 0.0)) return out;
  const size_t w = std::max<size_t>(3, static_cast<size_t>(std::lround(kSpliceWindow_s / dt_s)));
  if (imu.size() < 2 * w + 1) return out;
  const double quiet_mps2 = kSpliceQuiet_g * kStandardGravity_mps2;
  // The window's mean specific force, or nothing when a sample strays from it (the body was
  // accelerating: its mean is not gravity).
  auto quiet_mean = [&](size_t begin, size_t end) -> std::optional<Eigen::Vector3d> {
    Eigen::Vector3d dv = Eigen::Vector3d::Zero();
    double T_s = 0.0;
    for (size_t k = begin; k < end; ++k) {
      dv += imu[k].dv_mps;
      T_s += imu[k].dt_s;
    }
    const Eigen::Vector3d f_mps2 = dv / T_s;
    for (size_t k = begin; k < end; ++k)
      if ((imu[k].dv_mps / imu[k].dt_s - f_mps2).norm() > quiet_mps2) return std::nullopt;
    return f_mps2;
  };
  for (size_t k = w; k + w <= imu.size(); ++k) {
    // Cheap first: the join is one step of the specific force, larger than a quiet window allows.
    const Eigen::Vector3d step = imu[k].dv_mps / imu[k].dt_s - imu[k - 1].dv_mps / imu[k - 1].dt_s;
    if (step.norm() <= quiet_mps2) continue;
    const auto before = quiet_mean(k - w, k), after = quiet_mean(k, k + w);
    if (!before || !after) continue;
    const double turn_deg =
        std::acos(std::clamp(before->normalized().dot(after->normalized()), -1.0, 1.0)) / kDegToRad;
    double gyro_deg = 0.0;  // an upper bound of the body's turn: the increments' lengths summed
    for (size_t j = k - w; j < k + w; ++j) gyro_deg += imu[j].dtheta_rad.norm() / kDegToRad;
    if (!(turn_deg > kMinSpliceTurn_deg && gyro_deg < turn_deg / kSpliceGyroRatio)) continue;
    char buf[200];
    std::snprintf(buf, sizeof buf,
                  "a splice before t = %.2f s (gravity turned %.0f° in the body in one sample, the "
                  "gyros %.1f°: two pieces of recording joined)",
                  imu[k].t_s, turn_deg, gyro_deg);
    out.push_back({k, k + 1, buf});
    k += w;
  }
  return out;
}

std::vector<UnusableSpan> find_unusable_spans(const ImuSeries& imu) {
  std::vector<UnusableSpan> out = find_clipped_spans(imu);
  for (auto more : {find_time_gaps(imu), find_splices(imu)})
    out.insert(out.end(), more.begin(), more.end());
  std::stable_sort(out.begin(), out.end(),
                   [](const UnusableSpan& a, const UnusableSpan& b) { return a.begin < b.begin; });
  return out;
}

std::vector<const UnusableSpan*> spans_within(const std::vector<UnusableSpan>& spans, size_t begin,
                                              size_t end) {
  std::vector<const UnusableSpan*> out;
  for (const UnusableSpan& s : spans)
    if (s.begin < end && begin < s.end) out.push_back(&s);
  return out;
}

std::string reasons_text(const std::vector<const UnusableSpan*>& spans) {
  std::string out;
  for (const UnusableSpan* s : spans) out += (out.empty() ? "" : "; ") + s->reason;
  return out;
}

}  // namespace imucal::calib::core
