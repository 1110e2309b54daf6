#pragma once
// Internal to the run controller (run_controller.cpp, run_session.cpp): a live run's shared state
// and what its capture stages throw. Not part of the station's interface.
#include <chrono>
#include <cstdint>
#include <stdexcept>
#include <string>

#include "drivers/turntable/turntable_client.hpp"
#include "station/capture.hpp"
#include "station/run_controller.hpp"
#include "station/time_left.hpp"

namespace imucal::station {

using Clock = std::chrono::steady_clock;

struct RunController::Live {
  RunSnapshot snap;  // everything below: guarded by the controller's mutex
  RunPlan plan;
  bool reprocess = false;
  bool abort = false;
  std::string abort_reason;
  turntable::TurntableClient* client = nullptr;
  Capture* capture = nullptr;
  int step_index = -1;  // into plan.steps; -1 while preparing
  Clock::time_point step_started{};
  bool handed_to_worker = false;
  Clock::time_point stream_started{};  // when the first IMU samples arrived
  uint64_t rows_at_stream_start = 0;
  mutable TimeLeftEstimator time_left;  // active() is const; the estimate only ever shrinks
};

/// Moves longer than this are seen by the IMU (above rest_rate_threshold_dps at any realistic
/// table acceleration), so the rest after them waits for the motion in the IMU stream.
constexpr double kVisibleMoveDeg = 0.01;
/// How long (in IMU samples, as seconds at the configured rate) after a rest begins a commanded
/// move may still be invisible in the IMU stream before the run fails: a unit that does not turn
/// with the table never shows it.
constexpr double kMoveVisibleWithin_s = 5.0;

/// The operator (or SIGTERM) asked to stop; carries no text (the reason is in Live).
struct AbortRequested {};

/// The IMU side failed: run -> failed.
class CaptureFailure : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace imucal::station
