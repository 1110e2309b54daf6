#pragma once
// Simulated IMU CAN node: turns increments (from the truth simulator, calib::sim::simulate) into
// the frames of the IMU protocol (drivers/imu/PROTOCOL.md) on a CanChannel, with fault injection:
//   frame loss        each frame independently lost with probability frame_loss_probability;
//   corruption        each frame independently gets one random data bit flipped with probability
//                     corruption_probability (an error the bus CRC did not catch: the sample's
//                     CRC-16 must);
//   IMU reset         reset() or a scheduled reset_at_s: the IMU swallows the next
//                     reset_lost_samples increments (booting), then restarts its counter at 0 with
//                     status::kStartup on the first kStartupSamples samples.
// Everything injected is recorded (ImuCanNodeStats, SampleFate) so tests can compare the receiver's
// counters with the truth.
//
// send() puts one sample on the channel at once (for a caller with its own physics clock, like
// stationsim); run() sends a whole series paced at rate × speed_factor on CLOCK_MONOTONIC absolute
// deadlines (no drift). Whether a full transmit queue loses frames (counted in frames_refused) or
// makes the node wait is the channel's choice: drivers::imu::CanOpenOptions::write_timeout_ms.
#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <optional>
#include <random>
#include <vector>

#include "calib/core/imu_increment.hpp"
#include "drivers/imu/can_channel.hpp"
#include "drivers/imu/imu_codec.hpp"

namespace imucal::drivers::simulated {

struct ImuCanNodeOptions {
  double rate_hz = 100.0;     ///< the unit's sample rate (run() pacing)
  double speed_factor = 1.0;  ///< run(): simulated seconds per wall second; 0 = unpaced
  /// The unit's protocol (null: the built-in one) and where its identifiers start (unset: as in
  /// the protocol's DBC file).
  std::shared_ptr<const drivers::imu::ImuProtocolMap> protocol;
  std::optional<uint32_t> base_id;
  double frame_loss_probability = 0.0;  ///< per frame
  double corruption_probability = 0.0;  ///< per frame: one data bit flipped
  int reset_lost_samples = 5;           ///< increments swallowed by a reset
  std::vector<double> reset_at_s;       ///< resets when an increment with t_s >= each value is sent
  uint64_t seed = 1;
};

/// What happened to one increment given to send().
struct SampleFate {
  bool transmitted = false;  ///< false: swallowed by a reset
  uint32_t counter = 0;      ///< counter the IMU gave it (if transmitted)
  int frames_lost = 0;       ///< injected losses
  int frames_corrupted = 0;  ///< injected bit flips
  int frames_refused = 0;    ///< refused by a full transmit queue
  /// The frames as encoded, before any fault (what a perfect bus would carry).
  std::vector<drivers::imu::CanFrame> clean;
  bool intact() const {
    return transmitted && frames_lost + frames_corrupted + frames_refused == 0;
  }
};

struct ImuCanNodeStats {
  uint64_t increments_in = 0;        ///< increments given to send()
  uint64_t samples_transmitted = 0;  ///< samples put on the bus (any frame may have been faulted)
  uint64_t samples_faulted = 0;   ///< transmitted samples with a lost, corrupted or refused frame
  uint64_t frames_sent = 0;       ///< frames accepted by the channel (corrupted ones included)
  uint64_t frames_lost = 0;       ///< injected losses
  uint64_t frames_corrupted = 0;  ///< injected bit flips
  uint64_t frames_refused = 0;    ///< refused by a full transmit queue
  uint64_t resets = 0;
  uint64_t increments_lost_in_reset = 0;
};

class ImuCanNode {
 public:
  /// Throws std::invalid_argument for a probability outside [0, 1], a non-positive rate, a negative
  /// speed factor or negative reset_lost_samples.
  ImuCanNode(drivers::imu::CanChannel& channel, const ImuCanNodeOptions& options);

  /// Encodes one increment and sends its frames now, applying the fault injection.
  SampleFate send(const calib::core::ImuIncrement& increment, uint16_t status_flags = 0);

  /// Requests an IMU reset before the next send() (thread-safe).
  void reset() { reset_requested_.store(true); }

  /// Sends the series paced at rate_hz × speed_factor; returns early when *stop becomes true.
  /// `on_sample` (optional) is called after each send with the sample index and its fate.
  template <typename OnSample>
  void run(const calib::core::ImuSeries& series, const std::atomic<bool>* stop,
           OnSample&& on_sample);
  void run(const calib::core::ImuSeries& series, const std::atomic<bool>* stop = nullptr) {
    run(series, stop, [](std::size_t, const SampleFate&) {});
  }

  const ImuCanNodeStats& stats() const { return stats_; }
  const ImuCanNodeOptions& options() const { return options_; }

 private:
  /// Sleeps until sample k's deadline (start + k / (rate × speed)) on CLOCK_MONOTONIC.
  void pace(std::size_t k, int64_t start_ns) const;
  static int64_t monotonic_ns();

  drivers::imu::CanChannel& channel_;
  ImuCanNodeOptions options_;
  drivers::imu::ImuFrameEncoder encoder_;
  std::mt19937_64 rng_;
  std::uniform_real_distribution<double> uniform_{0.0, 1.0};
  std::atomic<bool> reset_requested_{false};
  int swallow_left_ = 0;
  std::size_t next_scheduled_reset_ = 0;
  ImuCanNodeStats stats_;
};

template <typename OnSample>
void ImuCanNode::run(const calib::core::ImuSeries& series, const std::atomic<bool>* stop,
                     OnSample&& on_sample) {
  const int64_t start = monotonic_ns();
  for (std::size_t k = 0; k < series.size(); ++k) {
    if (stop && stop->load()) return;
    pace(k, start);
    const SampleFate fate = send(series[k]);
    on_sample(k, fate);
  }
}

}  // namespace imucal::drivers::simulated
