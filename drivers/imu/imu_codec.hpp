#pragma once
// Encoder and decoder of an IMU's CAN frames, driven by its protocol file (imu_protocol_map.hpp;
// the built-in protocol, drivers/imu/PROTOCOL.md, unless another is given).
//
// Encoder: one ImuIncrement (+ status bits, temperature) -> the frames of one sample. The channels
// are quantised to their signal's resolution with the remainder carried into the next sample (as
// calib/sim/truth_sim.cpp's Quantiser does), so quantisation noise does not accumulate: the sum of
// the transmitted increments stays within half a resolution step of the sum of the true ones for
// any number of samples. A protocol of rates sends each increment divided by its dt_s.
//
// Decoder: stateful reassembly of samples from frames in any order, by the copy of the counter's
// low part every frame carries. A sample is output only when all its frames are present and the
// protocol's check over them matches (and the counter copies agree), so a lost, corrupted,
// duplicated or reordered frame can make a sample go missing but never produce a wrong one.
// Samples are output in counter order; an incomplete sample is waited for during
// `reorder_window_frames` received frames, then given up. Every anomaly is counted
// (DecoderCounters).
#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "calib/core/imu_increment.hpp"
#include "drivers/imu/can_frame.hpp"
#include "drivers/imu/imu_protocol.hpp"
#include "drivers/imu/imu_protocol_map.hpp"

namespace imucal::drivers::imu {

/// The protocol a codec uses: `protocol` (the built-in one when null) with its identifiers moved
/// to `base_id` when one is given (imu_protocol_map.hpp, with_base_id). Throws
/// std::invalid_argument when the ids leave their range or the station cannot carry the protocol.
std::shared_ptr<const ImuProtocolMap> resolve_protocol(
    std::shared_ptr<const ImuProtocolMap> protocol, std::optional<uint32_t> base_id);

class ImuFrameEncoder {
 public:
  /// The built-in protocol at `base_id`.
  explicit ImuFrameEncoder(uint32_t base_id = kDefaultImuBaseId, bool carry_remainder = true);
  ImuFrameEncoder(std::shared_ptr<const ImuProtocolMap> protocol, std::optional<uint32_t> base_id,
                  bool carry_remainder = true);

  /// The frames of the next sample, in transmission order. `status_flags` (imu_protocol.hpp's
  /// status bits, the simulator's vocabulary) are OR-ed with what the encoder sets itself
  /// (saturation, unknown temperature, startup); each raises its condition's signals in the
  /// protocol: gyro conditions the first signal of the list, accelerometer ones the second (the
  /// first when there is one), a failed built-in test the third (likewise).
  /// inc.t_s is not transmitted; inc.dt_s only turns increments into rates for such a protocol.
  /// Throws std::invalid_argument for a non-finite dθ or dv component.
  std::vector<CanFrame> encode(const calib::core::ImuIncrement& inc, uint16_t status_flags = 0);

  /// Power-up or reset of the IMU: the counter restarts at 0, the carried remainders are dropped
  /// and the next kStartupSamples samples carry the startup condition.
  void restart();

  uint32_t next_counter() const { return counter_; }
  /// The lowest identifier of the sample's messages.
  uint32_t base_id() const { return base_id_; }
  int frames_per_sample() const { return static_cast<int>(map_->messages.size()); }
  const ImuProtocolMap& protocol() const { return *map_; }

 private:
  double quantise(double increment, const DbcSignal& s, double scale, double dt_s, double& carry,
                  bool& clipped) const;
  uint32_t flags_for(uint16_t status, bool gyro_clip, bool accel_clip) const;

  std::shared_ptr<const ImuProtocolMap> map_;
  uint32_t base_id_ = 0;
  bool carry_remainder_;
  uint32_t counter_ = 0;
  int startup_left_ = kStartupSamples;
  std::array<double, 3> carry_dtheta_rad_{};
  std::array<double, 3> carry_dv_mps_{};
};

/// A decoded sample's conditions (DecodedSample::conditions).
namespace condition {
constexpr uint8_t kFault = 1U << 0;       ///< a fault flag of the protocol is set
constexpr uint8_t kSaturation = 1U << 1;  ///< a saturation flag is set
constexpr uint8_t kStartup = 1U << 2;     ///< a startup flag is set
constexpr uint8_t kTemperatureInvalid = 1U << 3;
}  // namespace condition

struct DecodedSample {
  /// dθ/dv are the channels' values (× dt_s for a protocol of rates); dt_s is the configured
  /// nominal interval; t_s = (sample_index + 1) × dt_s is the end of the interval on the stream's
  /// time axis (lost samples keep their slot); temp_c is NaN when the IMU reports it unknown or
  /// does not send it (a multiplexed temperature holds its last value between its pages).
  calib::core::ImuIncrement increment;
  uint32_t counter = 0;        ///< the IMU's sample counter (modulo 2^counter_bits)
  uint8_t conditions = 0;      ///< condition:: bits
  uint32_t flags = 0;          ///< bit i: the protocol's status flag i (ImuProtocolMap::flags) set
  uint64_t sample_index = 0;   ///< 0 for the first decoded sample; advances by the counter difference
                               ///< (after a reset/resync: by the receive-time gap in samples, ≥ 1)
  int64_t rx_time_ns = 0;      ///< receive time of the sample's last frame in protocol order
  bool discontinuity = false;  ///< first sample after an IMU reset or a counter resync
};

/// Counters of everything the decoder saw (monotonic; never reset by the decoder).
struct DecoderCounters {
  uint64_t frames_in = 0;            ///< every frame handed to push()
  uint64_t frames_used = 0;          ///< frames that became part of a decoded sample
  uint64_t foreign_frames = 0;       ///< other identifiers (other nodes on the bus): ignored
  uint64_t error_frames = 0;         ///< bus error frames (kCanErrFlag)
  uint64_t malformed_frames =
      0;  ///< our identifier with another length than the protocol's, or RTR
  uint64_t duplicate_frames = 0;     ///< identical to a frame already held or recently decoded
  uint64_t out_of_order_frames =
      0;                          ///< frames of decoded samples that arrived before a frame that
                                  ///< precedes them in protocol order (sample, then message order)
  uint64_t discarded_frames = 0;  ///< frames of samples that were not decoded (incomplete, check
                                  ///< failure, late) and conflicting extra candidates
  uint64_t samples_decoded = 0;
  uint64_t samples_lost = 0;         ///< counter gaps between consecutive decoded samples, any cause
  uint64_t samples_incomplete = 0;   ///< samples given up with frames missing
  uint64_t samples_corrupt = 0;      ///< complete samples failing the check (integrity failures)
  uint64_t samples_late = 0;         ///< valid samples arriving after a later one had been output
  uint64_t imu_resets = 0;           ///< counter restarts with the startup condition
  uint64_t resyncs = 0;              ///< counter jumps back beyond the late window without startup
};

struct DecoderOptions {
  std::shared_ptr<const ImuProtocolMap> protocol;  ///< null: the built-in protocol
  std::optional<uint32_t> base_id;                 ///< moves the protocol's identifiers
  double sample_rate_hz = 100.0;
  /// How many further frames an incomplete sample waits for its missing frames before it is given
  /// up; also bounds how long later, complete samples are held back to keep counter order.
  int reorder_window_frames = 16;
};

class ImuFrameDecoder {
 public:
  /// Throws std::invalid_argument for a non-positive rate, a window < 1, or a protocol the
  /// station cannot carry (resolve_protocol).
  explicit ImuFrameDecoder(const DecoderOptions& options = {});

  /// Feeds one received frame; samples completed by it are appended to `out` in counter order.
  void push(const ReceivedFrame& frame, std::vector<DecodedSample>& out);
  /// End of stream: gives up incomplete samples and outputs the held ones.
  void flush(std::vector<DecodedSample>& out);

  const DecoderCounters& counters() const { return counters_; }
  const DecoderOptions& options() const { return options_; }
  const ImuProtocolMap& protocol() const { return *map_; }
  /// "MESSAGE.SIGNAL, ..." of the flags set in `flags` that have one of `conditions`.
  std::string flag_names(uint32_t flags, uint8_t conditions) const;

 private:
  static constexpr int kMaxParts = kMaxSampleMessages;
  using Data = std::array<uint8_t, 8>;
  struct Candidate {
    Data data{};
    uint64_t arrival = 0;
    int64_t rx_time_ns = 0;
  };
  struct Slot {
    bool live = false;
    uint32_t tie = 0;
    uint64_t created_arrival = 0;
    std::array<std::array<Candidate, 2>, kMaxParts> cand{};
    std::array<int, kMaxParts> n{};
  };
  struct Verified {
    DecodedSample sample;
    uint32_t tie = 0;
    std::array<Data, kMaxParts> data{};
    std::array<uint64_t, kMaxParts> arrival{};
    uint64_t completed_at = 0;  ///< frames_in when it was verified
  };
  struct Recent {
    bool valid = false;
    uint64_t decoded_no = 0;
    std::array<Data, kMaxParts> data{};
  };

  int part_of(const CanFrame& f) const;  ///< -1: not ours
  uint32_t tie_of(int part, const Data& data) const;
  bool slot_complete(const Slot& s) const;
  int slot_total(const Slot& s) const;
  void complete(Slot& slot, std::vector<DecodedSample>& out);
  bool verify(const Slot& slot, const std::array<int, kMaxParts>& pick, Verified& v);
  void accept(Verified&& v, std::vector<DecodedSample>& out);
  void emit(Verified& v, bool discontinuity, std::vector<DecodedSample>& out);
  void release(std::vector<DecodedSample>& out, bool all);
  void abandon(Slot& slot);
  bool is_recent_duplicate(int part, const Data& data) const;
  uint32_t fwd(uint32_t to, uint32_t from) const { return (to - from) & counter_mask_; }

  static constexpr int kMaxSlots = 16;
  static constexpr int kMaxHeld = 16;
  static constexpr uint64_t kRecentSamples = 32;  ///< duplicate detection horizon

  DecoderOptions options_;
  std::shared_ptr<const ImuProtocolMap> map_;
  int parts_ = 0;
  double dt_s_;
  double to_increment_;  ///< dt_s for a protocol of rates, 1 for increments
  uint32_t counter_mask_ = 0, tie_mask_ = 0;
  uint32_t late_window_ = 0;   ///< a counter this far back is late, beyond: resync
  uint32_t restart_jump_ = 0;  ///< a startup sample this far from the last is an IMU reset
  uint32_t hold_span_ = 0;     ///< a gap within this many samples is held for (tie range)
  DecoderCounters counters_;
  std::array<Slot, kMaxSlots> slots_{};
  std::vector<Verified> held_;
  std::array<Recent, 256> recent_{};
  double last_temperature_c_;
  bool have_last_ = false;
  uint32_t last_counter_ = 0;
  uint8_t last_conditions_ = 0;
  int64_t last_rx_ns_ = 0;
  uint64_t last_index_ = 0;
  uint64_t max_arrival_out_ = 0;
};

}  // namespace imucal::drivers::imu
