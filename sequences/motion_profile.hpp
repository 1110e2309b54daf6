#pragma once
// Motion profile of a two-axis table: piecewise-constant angular acceleration per axis, so each
// axis angle is an exact quadratic in time inside a segment. The truth simulator evaluates it
// analytically at any instant; the estimators use its rest segments.
#include <string>
#include <vector>

namespace imucal::sequences {

/// State of one table axis at the start of a segment; the acceleration holds for the segment.
struct AxisMotion {
  double angle0_rad = 0.0;
  double rate0_radps = 0.0;
  double accel_radps2 = 0.0;
};

enum class SegmentKind { kRest, kMove };

struct ProfileSegment {
  double t0_s = 0.0;
  double t1_s = 0.0;
  SegmentKind kind = SegmentKind::kRest;
  AxisMotion outer;
  AxisMotion inner;
  int step_index = -1;  ///< index of the sequence step that produced it (0-based)
};

/// Angles, rates and accelerations of both axes at one instant.
struct TableState {
  double outer_rad = 0.0, outer_rate_radps = 0.0, outer_accel_radps2 = 0.0;
  double inner_rad = 0.0, inner_rate_radps = 0.0, inner_accel_radps2 = 0.0;
  bool at_rest = false;
};

struct MotionProfile {
  std::string name;                      ///< sequence name
  std::vector<ProfileSegment> segments;  ///< contiguous, ordered, first starts at t = 0

  double duration_s() const { return segments.empty() ? 0.0 : segments.back().t1_s; }
  /// Index of the segment containing t (t clamped to [0, duration]).
  size_t segment_index_at(double t_s) const;
  /// Exact table state at t.
  TableState at(double t_s) const;
  /// Segment boundaries (for splitting quadrature at discontinuities of acceleration).
  std::vector<double> breakpoints() const;
};

}  // namespace imucal::sequences
