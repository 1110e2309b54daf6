#pragma once
// Internal to the run controller (run_controller.cpp, run_session.cpp): a live run's shared state
// and what its capture stages throw. Not part of the station's interface.
#include <chrono>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "drivers/turntable/turntable_client.hpp"
#include "station/run/capture.hpp"
#include "station/run/run_controller.hpp"
#include "station/run/time_left.hpp"

namespace imucal::station::run {
using namespace station::config;
using namespace station::control;

using Clock = std::chrono::steady_clock;

/// One unit of a table run: its own run in the database, archive and capture.
struct RunController::Unit {
  RunSnapshot snap;                     // guarded by the controller's mutex, as everything below
  const ImuSlotConfig* slot = nullptr;  // the fixture slot (null: reprocess, import)
  Capture* capture = nullptr;           // while capturing
  uint64_t rows_at_stream_start = 0;
  bool handed_to_worker = false;  // complete and queued for calibration
  bool ended = false;             // terminal: stored (or being stored) as ended
};

/// A live table run: one or several units on the same table motion (issue #23), or one stored
/// run being reprocessed or imported.
struct RunController::Live {
  std::vector<Unit> units;  // [0]: the table run's first unit, whose run id joins the siblings
  RunPlan plan;             // everything below: guarded by the controller's mutex
  bool reprocess = false;
  bool abort = false;
  std::string abort_reason;
  drivers::turntable::TurntableClient* client = nullptr;
  int step_index = -1;  // into plan.steps; -1 while preparing
  Clock::time_point step_started{};
  bool capture_over = false;            // the table is done: units are calibrating or ended
  Clock::time_point stream_started{};   // when the first IMU samples arrived
  mutable TimeLeftEstimator time_left;  // active() is const; the estimate only ever shrinks

  bool all_ended() const {
    for (const Unit& u : units)
      if (!u.ended) return false;
    return true;
  }
  /// The first unit still capturing (the time-left estimate reads its rows), or null.
  const Unit* capturing_unit() const {
    for (const Unit& u : units)
      if (u.capture && !u.ended) return &u;
    return nullptr;
  }
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

/// The IMU side failed: run -> failed, the unit's FAILED — or STATION-FAULT where the CAN channel,
/// the bus or the archive failed (issue #50: the unit is not blamed for the station).
class CaptureFailure : public std::runtime_error {
 public:
  explicit CaptureFailure(const std::string& what,
                          db::history::RunVerdict verdict = db::history::RunVerdict::kFailed)
      : std::runtime_error(what), verdict_(verdict) {}
  db::history::RunVerdict verdict() const { return verdict_; }

 private:
  db::history::RunVerdict verdict_;
};

}  // namespace imucal::station::run
