#pragma once
// An IMU's CAN protocol as data (issue #27 item 2): a TOML file that names the unit's DBC file and
// maps its signals to what the station needs of one sample. Format (drivers/imu/PROTOCOL.md):
//
//   [protocol]  name, dbc (path relative to this file), quantity = "increments" | "rates"
//               (rad/s and m/s² integrated over the sample interval), completes_sample = the
//               message sent last, messages = every message of one sample in the order sent
//   [channels]  angular = [3 × "MESSAGE.SIGNAL"], velocity = [3 × ...], optional angular_scale,
//               velocity_scale (SI per unit of the DBC's physical value, default 1; never 0),
//               optional temperature = "MESSAGE.SIGNAL" (°C) and temperature_unknown = the raw
//               integer that means "unknown"
//   [counter]   parts = [{ signal = "MESSAGE.SIGNAL", bits = n, shift = s }, ...] (the counter is
//               Σ (raw & (2^bits - 1)) << shift; bits no wider than the signal), and optionally
//               same_in = ["MESSAGE.SIGNAL", ...]: copies of the low part that tie the frames of
//               one sample together
//   [status]    fault, saturation, startup, temperature_invalid = ["MESSAGE.SIGNAL", ...]
//               (non-zero = the condition; at most 32 flags in all)
//   [check]     kind = "none" | "crc16-ccitt-false" | "crc8-sae-j1850", signal = "MESSAGE.SIGNAL",
//               covers = ["MESSAGE" (all its bytes) | "MESSAGE:a-b" (bytes a..b)], in order
//
// Errors are std::invalid_argument naming the file and line (the protocol file's, or the DBC's):
// an unknown key, a missing or ill-typed one, a signal the DBC does not have, a scale of 0, a
// counter part wider than its signal, a channel that is multiplexed, a check signal inside what it
// covers, a sample of several messages one of which carries no copy of the counter's low part (its
// frames could not be told apart from another sample's).
#include <array>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "drivers/imu/dbc_database.hpp"

namespace imucal::drivers::imu {

/// A signal of the protocol's DBC: indices into DbcDatabase::messages and that message's signals.
struct DbcSignalRef {
  int message = -1, signal = -1;
  int position = -1;  ///< the message's place in the sample's `messages` (-1: not among them)
  std::string text;  ///< "MESSAGE.SIGNAL" as written
};

struct ImuProtocolMap {
  std::string path, name;
  DbcDatabase dbc;
  enum class Quantity { kIncrements, kRates };
  Quantity quantity = Quantity::kIncrements;
  std::vector<int> messages;  ///< of one sample, in the order sent (indices into dbc.messages)
  int completes_sample = -1;  ///< message index
  std::array<DbcSignalRef, 3> angular, velocity;
  double angular_scale = 1.0, velocity_scale = 1.0;
  struct CounterPart {
    DbcSignalRef ref;
    int bits = 8, shift = 0;
  };
  std::vector<CounterPart> counter;
  int counter_bits = 0;               ///< the widest shift + bits
  std::vector<DbcSignalRef> same_in;  ///< copies of the first part in the other frames
  DbcSignalRef temperature;           ///< message -1: not carried
  std::optional<int64_t> temperature_unknown;  ///< raw value meaning "unknown"
  std::vector<DbcSignalRef> fault, saturation, startup, temperature_invalid;
  /// Every status flag, in the order fault, saturation, startup, temperature_invalid (a sample's
  /// `flags` bit i is flags[i]).
  enum class Condition { kFault, kSaturation, kStartup, kTemperatureInvalid };
  struct StatusFlag {
    DbcSignalRef ref;
    Condition condition = Condition::kFault;
  };
  std::vector<StatusFlag> flags;
  /// Per position in `messages`: the signal that ties the frame to its sample (the counter's low
  /// part, or its copy in that message).
  std::vector<DbcSignalRef> tie;
  struct ByteRange {
    int message = -1, first = 0, last = 0;  ///< bytes first..last of the message
    int position = -1;                      ///< the message's place in the sample
  };
  enum class Check { kNone, kCrc16CcittFalse, kCrc8SaeJ1850 };
  Check check = Check::kNone;
  DbcSignalRef check_signal;
  std::vector<ByteRange> check_covers;

  const DbcMessage& message(int i) const { return dbc.messages[static_cast<size_t>(i)]; }
  const DbcSignal& signal(const DbcSignalRef& r) const {
    return message(r.message).signals[static_cast<size_t>(r.signal)];
  }
};

/// Parses a protocol file's text; `path` names it and locates a relative DBC path. With
/// `dbc_text`, that is the DBC's text (the file named in [protocol] dbc is not read).
ImuProtocolMap parse_protocol_map(const std::string& text, const std::string& path,
                                  const std::string* dbc_text = nullptr);
/// Reads and parses a protocol file (and the DBC file it names).
ImuProtocolMap read_protocol_map(const std::string& path);

/// The built-in protocol (drivers/imu/protocols/imucal-imu-1.toml and imu.dbc, compiled in; the
/// same bytes are installed under /usr/share/imucal/protocols/). Parsed once.
std::shared_ptr<const ImuProtocolMap> builtin_protocol_map();

/// The lowest identifier of the sample's messages (what base_id moves).
uint32_t lowest_id(const ImuProtocolMap& map);

/// The protocol with its identifiers moved so that the lowest of the sample's messages is
/// `base_id` (the others keep their distances): a second unit of the same kind on the same bus.
/// Throws std::invalid_argument naming the protocol when an identifier leaves its 11- or 29-bit
/// range.
ImuProtocolMap with_base_id(ImuProtocolMap map, uint32_t base_id);

/// One sample's increment resolution as the protocol carries it: the coarsest channel's step
/// (|factor × scale|; × dt_s for a protocol of rates). The run archive's [noise] LSBs.
struct IncrementResolution {
  double dtheta_rad = 0.0, dv_mps = 0.0;
};
IncrementResolution increment_resolution(const ImuProtocolMap& map, double dt_s);

/// Why the station's CAN channel cannot carry this protocol ("" when it can): it carries classic
/// frames (up to 8 bytes), and at most kMaxSampleMessages of them per sample.
constexpr int kMaxSampleMessages = 8;
std::string station_unsupported(const ImuProtocolMap& map);

}  // namespace imucal::drivers::imu
