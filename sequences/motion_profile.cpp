#include "sequences/motion_profile.hpp"

#include <algorithm>

namespace imucal::sequences {

size_t MotionProfile::segment_index_at(double t_s) const {
  // First segment whose end is >= t; segments are contiguous and sorted.
  auto it = std::lower_bound(segments.begin(), segments.end(), t_s,
                             [](const ProfileSegment& s, double t) { return s.t1_s < t; });
  if (it == segments.end()) return segments.empty() ? 0 : segments.size() - 1;
  return static_cast<size_t>(it - segments.begin());
}

TableState MotionProfile::at(double t_s) const {
  TableState st;
  if (segments.empty()) return st;
  const ProfileSegment& seg = segments[segment_index_at(t_s)];
  const double tau = std::clamp(t_s, seg.t0_s, seg.t1_s) - seg.t0_s;
  auto eval = [tau](const AxisMotion& a, double& ang, double& rate, double& acc) {
    ang = a.angle0_rad + a.rate0_radps * tau + 0.5 * a.accel_radps2 * tau * tau;
    rate = a.rate0_radps + a.accel_radps2 * tau;
    acc = a.accel_radps2;
  };
  eval(seg.outer, st.outer_rad, st.outer_rate_radps, st.outer_accel_radps2);
  eval(seg.inner, st.inner_rad, st.inner_rate_radps, st.inner_accel_radps2);
  st.at_rest = seg.kind == SegmentKind::kRest;
  return st;
}

std::vector<double> MotionProfile::breakpoints() const {
  std::vector<double> b;
  b.reserve(segments.size() + 1);
  for (const auto& s : segments) b.push_back(s.t0_s);
  if (!segments.empty()) b.push_back(segments.back().t1_s);
  return b;
}

}  // namespace imucal::sequences
