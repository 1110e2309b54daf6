#pragma once
// The gap check's false-alarm rate per run: how often a run without any unmodelled effect is
// called significant (issue #28, #22). Measured on null runs of every shipped sequence, from the
// project's simulator and an independent one: tools/bench_false_alarm.sh, figures in the README.
namespace imucal::calib::diagnosis {

/// The station's rate by default ([calibration] gap_false_alarm): a line of 300 units a day sees
/// one needless review in about a month, and CI's 15-run soak fails once in ~670 runs of it.
constexpr double kDefaultGapFalseAlarm = 1e-4;

}  // namespace imucal::calib::diagnosis
