#pragma once
// Stretches of a field recording no method may rely on (issue #48 item 3): a channel clipped at
// the sensor's range, samples dropped by the logger, or a splice where two pieces were joined. A
// real recording has them here and there; they spoil the move or the rest they fall in, not the
// run. The input carries them (CalibrationInput::unusable), the rest detection ends a rest at them,
// and each method leaves out what they touch (the legacy fit the move, the AINS the attitude it
// carried across) and says so, instead of the whole run being refused.
#include <cstddef>
#include <string>
#include <vector>

#include "calib/core/imu_increment.hpp"

namespace imucal::calib::core {

/// Half-open sample range [begin, end) of the IMU series, and why it cannot be used, for the
/// person reading the result: "gyro x clipped at 250 °/s (10 samples)", "5 samples missing".
struct UnusableSpan {
  size_t begin = 0;
  size_t end = 0;
  std::string reason;
};

/// Rates below these are never a sensor's range: no gyro made clips below 100 °/s (the smallest
/// ranges are 125 and 250 °/s) and no accelerometer below 1.5 g (the smallest is ±2 g). A plateau
/// at a lower extreme is a smooth peak whose quantised samples happen to repeat.
inline constexpr double kMinGyroRange_degps = 100.0;
inline constexpr double kMinAccelRange_g = 1.5;

/// Clipped stretches: per channel and sign, two or more consecutive samples at exactly the
/// channel's extreme value in that direction, where that extreme is beyond the floors above
/// (ranges are in standard g).
std::vector<UnusableSpan> find_clipped_spans(const ImuSeries& imu);

/// The recording's sample interval: the median of its samples' dt_s (0 for no sample).
double median_interval_s(const ImuSeries& imu);

/// Dropped samples: every sample whose interval dt_s exceeds 1.5 times the median interval. The
/// span is that one sample (its increment does not describe the time it covers).
std::vector<UnusableSpan> find_time_gaps(const ImuSeries& imu);

/// Splices: where two stretches of a recording were joined (an annotated session whose sections
/// were cut out and concatenated, a logger restarted into the same file). The accelerometers' mean
/// over a window of kSpliceWindow_s before a sample and one after it point more than
/// kMinSpliceTurn_deg apart, with both windows quiet (each sample within kSpliceQuiet_g of its
/// window's mean), while the gyros turned less than 1/kSpliceGyroRatio of that across both
/// windows: gravity moved in the body and nothing turned the body. The span is the first sample
/// after the join. A knock (a one-sample spike of several g) leaves gravity where it was; a turn,
/// however fast, is on the gyros; a hand's push tilts the specific force by its acceleration while
/// the body turns a few degrees with it (measured on the corpus' hand-turned recordings: up to 18°
/// against at least 1/10 of it on the gyros, where the joins of MaD Lab's annotated session turn
/// gravity 89–178° with the gyros at 0.0–0.1°). The floor of 10° keeps an uncalibrated gyro's
/// offset (3.3 °/s over the two windows: 0.66°) from hiding a join.
std::vector<UnusableSpan> find_splices(const ImuSeries& imu);
inline constexpr double kMinSpliceTurn_deg = 10.0;
inline constexpr double kSpliceGyroRatio = 20.0;
inline constexpr double kSpliceQuiet_g = 0.15;
inline constexpr double kSpliceWindow_s = 0.1;

/// The three kinds, ordered by their first sample.
std::vector<UnusableSpan> find_unusable_spans(const ImuSeries& imu);

/// The spans that share a sample with [begin, end).
std::vector<const UnusableSpan*> spans_within(const std::vector<UnusableSpan>& spans, size_t begin,
                                              size_t end);

/// "gyro x clipped at 250 °/s (10 samples); 3 samples missing": the reasons of `spans`, joined.
std::string reasons_text(const std::vector<const UnusableSpan*>& spans);

}  // namespace imucal::calib::core
