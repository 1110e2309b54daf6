#pragma once
// imucal's exit codes (README "imucal in brief"): 0 done, 1 bad input or a failed calibration,
// 2 a usage error, 3 a verdict of REVIEW (a gap the diagnosis could not explain, a design that
// misses its targets). One definition for main.cpp and the commands that return them.

namespace imucal::tools::imucal {

inline constexpr int kExitBadInput = 1;
inline constexpr int kExitUsage = 2;
inline constexpr int kExitReview = 3;

}  // namespace imucal::tools::imucal
