#pragma once
// Encoder and decoder of the IMU CAN protocol (drivers/imu/PROTOCOL.md, imu_protocol.hpp).
//
// Encoder: one ImuIncrement (+ status bits, temperature) -> the 4 frames of one sample. dθ and dv
// are quantised to the LSB with the remainder carried into the next sample (as
// calib/sim/truth_sim.cpp's Quantiser does), so quantisation noise does not accumulate: the sum of
// the transmitted increments stays within half an LSB of the sum of the true increments for any
// number of samples.
//
// Decoder: stateful reassembly of samples from frames in any order, by the counter in byte 0 of
// every frame. A sample is output only when all 4 frames are present and the CRC-16 over them
// matches, so a lost, corrupted, duplicated or reordered frame can make a sample go missing but
// never produce a wrong one. Samples are output in counter order; an incomplete sample is waited
// for during `reorder_window_frames` received frames, then given up. Every anomaly is counted
// (DecoderCounters).
#include <array>
#include <cstdint>
#include <vector>

#include "calib/core/imu_increment.hpp"
#include "drivers/imu/can_frame.hpp"
#include "drivers/imu/imu_protocol.hpp"

namespace imucal::imu {

class ImuFrameEncoder {
 public:
  explicit ImuFrameEncoder(uint32_t base_id = kDefaultImuBaseId, bool carry_remainder = true);

  /// The 4 frames of the next sample, in transmission order (X, Y, Z, status). `status_flags` are
  /// OR-ed with the bits the encoder sets itself (saturation, unknown temperature, startup).
  /// inc.t_s and inc.dt_s are not transmitted (the rate is a property of the unit's configuration).
  /// Throws std::invalid_argument for a non-finite dθ or dv component.
  std::array<CanFrame, kFramesPerSample> encode(const calib::ImuIncrement& inc, uint16_t status_flags = 0);

  /// Power-up or reset of the IMU: the counter restarts at 0, the carried remainders are dropped and
  /// the next kStartupSamples samples carry status::kStartup.
  void restart();

  uint16_t next_counter() const { return counter_; }
  uint32_t base_id() const { return base_id_; }

 private:
  int32_t quantise(double x, double lsb, int64_t min_count, int64_t max_count, double& carry, bool& clipped);

  uint32_t base_id_;
  bool carry_remainder_;
  uint16_t counter_ = 0;
  int startup_left_ = kStartupSamples;
  std::array<double, 3> carry_dtheta_rad_{};
  std::array<double, 3> carry_dv_mps_{};
};

struct DecodedSample {
  /// dθ/dv are count × LSB exactly; dt_s is the configured nominal interval; t_s = (sample_index + 1)
  /// × dt_s is the end of the interval on the stream's time axis (lost samples keep their slot);
  /// temp_c is NaN when the IMU reports it unknown.
  calib::ImuIncrement increment;
  uint16_t counter = 0;        ///< the IMU's 16-bit sample counter
  uint16_t status = 0;         ///< status word (imu_protocol.hpp, namespace status)
  uint64_t sample_index = 0;   ///< 0 for the first decoded sample; advances by the counter difference
                               ///< (after a reset/resync: by the receive-time gap in samples, ≥ 1)
  int64_t rx_time_ns = 0;      ///< receive time of the sample's status frame
  bool discontinuity = false;  ///< first sample after an IMU reset or a counter resync
};

/// Counters of everything the decoder saw (monotonic; never reset by the decoder).
struct DecoderCounters {
  uint64_t frames_in = 0;            ///< every frame handed to push()
  uint64_t frames_used = 0;          ///< frames that became part of a decoded sample
  uint64_t foreign_frames = 0;       ///< other identifiers (other nodes on the bus): ignored
  uint64_t error_frames = 0;         ///< bus error frames (kCanErrFlag)
  uint64_t malformed_frames = 0;     ///< our identifier with a length other than 8, or RTR
  uint64_t duplicate_frames = 0;     ///< identical to a frame already held or recently decoded
  uint64_t out_of_order_frames = 0;  ///< frames of decoded samples that arrived before a frame that
                                     ///< precedes them in protocol order (sample, then X, Y, Z, status)
  uint64_t discarded_frames = 0;     ///< frames of samples that were not decoded (incomplete, CRC
                                     ///< failure, late) and conflicting extra candidates
  uint64_t samples_decoded = 0;
  uint64_t samples_lost = 0;         ///< counter gaps between consecutive decoded samples, any cause
  uint64_t samples_incomplete = 0;   ///< samples given up with frames missing
  uint64_t samples_corrupt = 0;      ///< complete samples failing the CRC (integrity failures)
  uint64_t samples_late = 0;         ///< valid samples arriving after a later one had been output
  uint64_t imu_resets = 0;           ///< counter restarts with status::kStartup
  uint64_t resyncs = 0;              ///< counter jumps back beyond the late window without kStartup
};

struct DecoderOptions {
  uint32_t base_id = kDefaultImuBaseId;
  double sample_rate_hz = 100.0;
  /// How many further frames an incomplete sample waits for its missing frames before it is given
  /// up; also bounds how long later, complete samples are held back to keep counter order.
  int reorder_window_frames = 4 * kFramesPerSample;
};

class ImuFrameDecoder {
 public:
  /// Throws std::invalid_argument for a non-positive rate or a window < 1.
  explicit ImuFrameDecoder(const DecoderOptions& options = {});

  /// Feeds one received frame; samples completed by it are appended to `out` in counter order.
  void push(const ReceivedFrame& frame, std::vector<DecodedSample>& out);
  /// End of stream: gives up incomplete samples and outputs the held ones.
  void flush(std::vector<DecodedSample>& out);

  const DecoderCounters& counters() const { return counters_; }
  const DecoderOptions& options() const { return options_; }

 private:
  struct Candidate {
    std::array<uint8_t, 8> data{};
    uint64_t arrival = 0;
    int64_t rx_time_ns = 0;
  };
  struct Slot {
    bool live = false;
    uint8_t counter_lo = 0;
    uint64_t created_arrival = 0;
    std::array<std::array<Candidate, 2>, kFramesPerSample> cand{};
    std::array<int, kFramesPerSample> n{};
    int total() const { return n[0] + n[1] + n[2] + n[3]; }
  };
  struct Verified {
    DecodedSample sample;
    std::array<std::array<uint8_t, 8>, kFramesPerSample> data{};
    std::array<uint64_t, kFramesPerSample> arrival{};
    uint64_t completed_at = 0;  ///< frames_in when it was verified
  };
  struct Recent {
    bool valid = false;
    uint64_t decoded_no = 0;
    std::array<std::array<uint8_t, 8>, kFramesPerSample> data{};
  };

  void complete(Slot& slot, std::vector<DecodedSample>& out);
  void accept(Verified&& v, std::vector<DecodedSample>& out);
  void emit(Verified& v, bool discontinuity, std::vector<DecodedSample>& out);
  void release(std::vector<DecodedSample>& out, bool all);
  void abandon(Slot& slot);
  bool is_recent_duplicate(int part, const std::array<uint8_t, 8>& data) const;

  static constexpr int kMaxSlots = 16;
  static constexpr int kMaxHeld = 16;
  static constexpr uint64_t kRecentSamples = 32;   ///< duplicate detection horizon
  static constexpr uint32_t kLateWindow = 256;     ///< a counter this far back is late, beyond: resync

  DecoderOptions options_;
  double dt_s_;
  DecoderCounters counters_;
  std::array<Slot, kMaxSlots> slots_{};
  std::vector<Verified> held_;
  std::array<Recent, 256> recent_{};
  bool have_last_ = false;
  uint16_t last_counter_ = 0;
  uint16_t last_status_ = 0;
  int64_t last_rx_ns_ = 0;
  uint64_t last_index_ = 0;
  uint64_t max_arrival_out_ = 0;
};

}  // namespace imucal::imu
