#pragma once
// The daemon's IMU capture: its own thread reads the IMU's CanChannel (poll on its fd), decodes the
// samples (drivers::imu::ImuFrameDecoder) and, while an ArchiveWriter is attached, writes the run
// archive as it goes: every received frame into capture.log, one imu.csv + table.csv row per IMU
// sample slot. It is independent of the control thread, which only tells it what the table does
// (table_moving / begin_rest) and waits for rests to complete (wait_rest_done).
//
// Rows (ARCHITECTURE §5, db/archive/FORMAT.md), counted from attach():
//  * row r has t_s = (r + 1) / rate_hz: one row per sample slot of the IMU's counter;
//  * lost samples (counter gaps of up to max_gap_samples) become rows interpolated linearly in dθ
//    and dv between the neighbouring decoded samples (counted in samples_filled); a longer gap is a
//    fault;
//  * table.csv: the latest angles the control thread gave (sample-and-hold while moving, the
//    in-position reading during a rest) and at_rest:
//      begin_rest() -> rows stay at_rest = 0 until settle_guard_samples consecutive still samples
//      (|dθ|/dt <= rest_rate_threshold_dps) were seen; the next rest_samples rows get at_rest = 1;
//      then wait_rest_done() returns true. Motion above the threshold during those rows is a fault.
// Rest durations are counted in IMU samples, never in wall time, so an accelerated simulation
// yields the same archive as real time.
//
// Faults (fault() returns a one-line reason naming the row and its time): IMU reset or counter
// resync, a gap longer than max_gap_samples, no IMU sample for stream_timeout while attached, the
// CAN controller going bus-off (an error frame of that class; other error frames are only counted),
// motion during a counted rest, IMU-reported failures (status bits: gyro/accel fault, built-in test
// failure, saturation), CAN channel or archive I/O errors. After a fault no more rows are written;
// frames are still logged to capture.log (the raw record of what happened), except after an archive
// I/O error, which stops all writes.
//
// Counters (stats()) are counted from the latest attach() (from start() before any attach).
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "calib/core/imu_increment.hpp"
#include "drivers/imu/can_channel.hpp"
#include "drivers/imu/imu_codec.hpp"
#include "station/run/archive_writer.hpp"
#include "station/run/capture_stats.hpp"

namespace imucal::station::run {

struct CaptureOptions {
  drivers::imu::DecoderOptions decoder;   ///< base_id, rate
  uint64_t max_gap_samples = 10;          ///< longer gap -> fault
  uint64_t settle_guard_samples = 50;     ///< still samples before a rest's counted samples begin
  double rest_rate_threshold_dps = 0.05;  ///< |dθ|/dt above this = the unit is moving
  std::chrono::milliseconds stream_timeout{
      2000};  ///< no sample this long (while attached) -> fault
  std::chrono::milliseconds flush_period{200};
  std::chrono::milliseconds poll_timeout{20};  ///< capture thread's poll(2) timeout (stop latency)
};

class Capture {
 public:
  /// Throws std::invalid_argument for a null channel or bad options (non-positive rate, threshold,
  /// timeouts or flush period).
  Capture(std::unique_ptr<drivers::imu::CanChannel> channel, CaptureOptions options);
  ~Capture();  ///< stop()
  Capture(const Capture&) = delete;
  Capture& operator=(const Capture&) = delete;

  /// Starts the capture thread (reading and decoding; nothing is written before attach()).
  void start();
  /// Stops and joins the thread (within about poll_timeout). Idempotent.
  void stop();

  /// True once the stream is live: a sample decodes after this call, within timeout.
  bool wait_for_stream(std::chrono::milliseconds timeout);
  /// Samples received since the current rest began while the last commanded move has still not
  /// shown in the IMU stream (0 once it has): a unit that does not turn with the table, or whose
  /// gyro axis of that rotation is dead, never shows it.
  uint64_t unseen_move_samples() const;
  /// From the next frame/sample on: frames into capture.log, rows into imu.csv/table.csv. Resets
  /// the row count, the fault and the counters; keeps the table state given so far. The writer
  /// must outlive detach().
  void attach(ArchiveWriter* writer);
  /// Flushes the writer; no more writes. A flush error becomes the fault.
  void detach();

  // Table side (control thread). Rows get at_rest = 0 and the latest angles given here.
  void table_moving(double outer_deg, double inner_deg);
  /// A move has been commanded: the next rest's still samples only count once the IMU stream has
  /// shown motion above the threshold after this call. The IMU stream can lag the Modbus readings
  /// (a starved capture thread leaves a backlog in the socket), so without this the still samples
  /// recorded before the move would be counted as the rest at the new pose. Call it before
  /// move_to for every move long enough to be seen (any move of more than a few millidegrees).
  void move_commanded();
  /// Rest at these angles: after settle_guard_samples consecutive still samples, the next
  /// rest_samples rows get at_rest = 1 (motion above the threshold during them -> fault).
  void begin_rest(double outer_deg, double inner_deg, uint64_t rest_samples);
  /// True when the rest begun last has all its rows; false on timeout or fault (check fault()).
  bool wait_rest_done(std::chrono::milliseconds timeout);

  CaptureStats stats() const;
  std::optional<std::string> fault() const;
  /// Whether the fault is the station's (issue #50): the CAN channel or bus failed, or the
  /// archive could not be written — not the unit's stream or motion.
  bool fault_is_station() const;
  /// Sample slots per wall second over the last ~2 s (for time-left estimates); 0 until known.
  double sample_rate_observed_hz() const;
  uint64_t rows() const;
  /// at_rest rows written of the rest begun last (progress of a rest).
  uint64_t rest_rows_done() const;
  const CaptureOptions& options() const { return options_; }

 private:
  enum class Phase { kIdle, kMoving, kSettling, kResting, kRestDone };
  using Clock = std::chrono::steady_clock;

  void run();
  void on_frames(const std::vector<drivers::imu::ReceivedFrame>& frames, Clock::time_point now);
  void on_sample(const drivers::imu::DecodedSample& s, Clock::time_point now);
  void on_bus_off();  ///< an error frame of class bus-off: a fault while attached
  bool emit_row(const calib::core::ImuIncrement& inc);          ///< false: fault, nothing written
  double rate_dps(const calib::core::ImuIncrement& inc) const;  ///< |dθ|/dt in deg/s
  bool is_moving(const calib::core::ImuIncrement& inc) const;   ///< above rest_rate_threshold_dps
  /// The first fault wins; `station` says whose it is (fault_is_station()).
  void set_fault(std::string reason, bool station = false);
  void writer_failed(const std::exception& e);
  std::string row_label(uint64_t row) const;  ///< "row N (t = X s)"
  CaptureStats raw_counters() const;

  std::unique_ptr<drivers::imu::CanChannel> channel_;
  CaptureOptions options_;
  drivers::imu::ImuFrameDecoder decoder_;
  double dt_s_;

  std::thread thread_;
  bool running_ = false;
  std::atomic<bool> stop_{false};

  mutable std::mutex mu_;
  std::condition_variable cv_;
  ArchiveWriter* writer_ = nullptr;
  bool writes_disabled_ = false;  ///< archive I/O error: no more writes at all
  std::optional<std::string> fault_;
  bool fault_is_station_ = false;
  int64_t rest_begun_ns_ = 0;  ///< realtime of the latest begin_rest (the receive-time domain)

  // Cumulative counters (since start); stats() subtracts baseline_ (taken at attach).
  uint64_t frames_received_ = 0, frames_logged_ = 0, rx_overflow_ = 0;
  drivers::imu::DecoderCounters dec_;
  CaptureStats baseline_;
  /// The counters at detach: a run's counters end with its archive (frames that arrive between
  /// detach and stop are no run's; issue #19 item 11: 384 196 logged of 384 197 received).
  std::optional<CaptureStats> end_counters_;
  uint64_t samples_filled_ = 0, max_gap_ = 0, rows_ = 0, rest_rows_ = 0;

  // Stream liveness and rate.
  uint64_t samples_seen_ = 0;
  Clock::time_point last_sample_time_{};
  bool have_prev_any_ = false;
  uint64_t prev_index_any_ = 0;
  uint64_t slots_seen_ = 0;  ///< sample slots (decoded + lost) since start
  std::deque<std::pair<Clock::time_point, uint64_t>> rate_window_;

  // Rows.
  bool have_prev_row_ = false;
  uint64_t prev_row_index_ = 0;
  calib::core::ImuIncrement prev_row_inc_;

  // Table state.
  Phase phase_ = Phase::kIdle;
  double outer_deg_ = 0.0, inner_deg_ = 0.0;
  uint64_t still_run_ = 0, rest_left_ = 0, rest_done_rows_ = 0;
  bool motion_pending_ = false;       ///< move_commanded() and no moving sample seen since
  uint64_t unseen_move_samples_ = 0;  ///< samples since begin_rest() with the move still unseen
  bool rest_done_ = false;
  uint64_t rest_generation_ = 0;
};

}  // namespace imucal::station::run
