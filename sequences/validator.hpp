#pragma once
// Checks a parsed Sequence against turntable limits and the calibration's needs (rest before and
// after every rotation). The observability (rank / CRLB) check is not here: it needs the error
// model and lives in calib/; the tools apply it.
#include <limits>
#include <string>
#include <vector>

#include "sequences/sequence.hpp"

namespace imucal::sequences {

struct TableLimits {
  double max_rate_dps = 20.0;
  double max_accel_dps2 = 10.0;
  double min_rest_s = 10.0;
  double max_duration_s = 3600.0 * 1.5;
  double inner_min_deg = -std::numeric_limits<double>::infinity();
  double inner_max_deg = std::numeric_limits<double>::infinity();
  double outer_min_deg = -std::numeric_limits<double>::infinity();
  double outer_max_deg = std::numeric_limits<double>::infinity();
};

struct ValidationIssue {
  std::string message;
  int line = 0;         ///< source line (0 = the file as a whole)
  int step_index = -1;  ///< 0-based step index; -1 for [start] or whole-sequence issues
};

/// The limits a sequence is checked against: the station's, tightened by the file's [limits]
/// (a file can restrict, never relax, what the station allows).
TableLimits effective_limits(const TableLimits& station, const DeclaredLimits& declared);

/// All issues, in step order. Checks: rate / acceleration over limits, non-positive or non-finite
/// values, rests shorter than min_rest_s (the initial one included), commanded angles outside the
/// axis limits (tracked through the steps), total duration over the limit, no rotation at all, a
/// rotation not followed by a rest (each rotation needs a rest before and after it), a rotation of
/// zero angle.
std::vector<ValidationIssue> validate(const Sequence& seq, const TableLimits& limits);

/// Throws the first issue as SequenceError(seq.source_path, line, message [+ count of others]).
void throw_if_issues(const Sequence& seq, const std::vector<ValidationIssue>& issues);

/// validate() + throw_if_issues().
void validate_or_throw(const Sequence& seq, const TableLimits& limits);

}  // namespace imucal::sequences
