#pragma once
// In-memory form of a rotation-sequence file (format: sequences/FORMAT.md). Angles and rates are
// kept in the file's units (degrees, seconds) here; the profile generator converts to radians.
// Every element remembers the source line it came from, so the validator can point at it.
#include <optional>
#include <string>
#include <vector>

namespace imucal::sequences {

enum class StepKind { kRotate, kRest };
enum class Axis { kOuter, kInner };

inline const char* axis_name(Axis a) { return a == Axis::kOuter ? "outer" : "inner"; }

/// One [[step]]: either a single-axis rotation or a rest period.
struct Step {
  StepKind kind = StepKind::kRest;
  // Rotation (kind == kRotate): exactly one of by_deg (relative) / to_deg (absolute) is set.
  // to_deg moves the axis by (to_deg - current commanded angle): no wrap-around, so an unlimited
  // axis may accumulate more than 360 deg.
  Axis axis = Axis::kOuter;
  std::optional<double> by_deg;
  std::optional<double> to_deg;
  double rate_dps = 0.0;    ///< cruise rate magnitude (step value or [defaults])
  double accel_dps2 = 0.0;  ///< acceleration magnitude (step value or [defaults])
  // Rest (kind == kRest).
  double duration_s = 0.0;

  // Source lines (1-based, 0 = unknown) for error messages.
  int line = 0;        ///< the [[step]] header
  int value_line = 0;  ///< by_deg / to_deg / rest_s key
  int rate_line = 0;   ///< rate_dps key (of the step or of [defaults])
  int accel_line = 0;  ///< accel_dps2 key (of the step or of [defaults])
};

/// [start]: where the table is at t = 0 and how long it rests there before the first step.
struct Start {
  double outer_deg = 0.0;
  double inner_deg = 0.0;
  double rest_s = 0.0;  ///< initial rest period
  int line = 0;
  int rest_line = 0;
};

/// Optional [limits] the file was written for (e.g. a table with limited inner-axis travel).
/// They can only tighten the station's limits (see validator.hpp: effective_limits).
struct DeclaredLimits {
  std::optional<double> max_rate_dps;
  std::optional<double> max_accel_dps2;
  std::optional<double> min_rest_s;
  std::optional<double> max_duration_s;
  std::optional<double> inner_min_deg, inner_max_deg;
  std::optional<double> outer_min_deg, outer_max_deg;
  int line = 0;  ///< the [limits] header, 0 if absent
};

struct Sequence {
  std::string name;
  std::string description;
  std::string source_path;  ///< file it was read from (or the origin label of a string)
  Start start;
  std::vector<Step> steps;
  DeclaredLimits limits;
};

}  // namespace imucal::sequences
