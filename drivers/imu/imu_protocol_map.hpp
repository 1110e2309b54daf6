#pragma once
// An IMU's CAN protocol as data (issue #27 item 2): a TOML file that names the unit's DBC file and
// maps its signals to what the station needs of one sample. Format (drivers/imu/PROTOCOLS.md):
//
//   [protocol]  name, dbc (path relative to this file), quantity = "increments" | "rates"
//               (rad/s and m/s² integrated over the sample interval), completes_sample = the
//               message sent last, messages = every message of one sample in the order sent
//   [channels]  angular = [3 × "MESSAGE.SIGNAL"], velocity = [3 × ...], optional angular_scale,
//               velocity_scale (SI per unit of the DBC's physical value, default 1; never 0)
//   [counter]   parts = [{ signal = "MESSAGE.SIGNAL", bits = n, shift = s }, ...] (the counter is
//               Σ (raw & (2^bits - 1)) << shift; bits no wider than the signal), and optionally
//               same_in = ["MESSAGE.SIGNAL", ...]: copies of the low part that tie the frames of
//               one sample together
//   [status]    fault, saturation, startup = ["MESSAGE.SIGNAL", ...] (non-zero = the condition)
//   [check]     kind = "none" | "crc16-ccitt-false" | "crc8-sae-j1850", signal = "MESSAGE.SIGNAL",
//               covers = ["MESSAGE" (all its bytes) | "MESSAGE:a-b" (bytes a..b)], in order
//
// Errors are std::invalid_argument naming the file and line (the protocol file's, or the DBC's):
// an unknown key, a missing or ill-typed one, a signal the DBC does not have, a scale of 0, a
// counter part wider than its signal, a channel that is multiplexed, a check signal inside what it
// covers.
#include <array>
#include <string>
#include <vector>

#include "drivers/imu/dbc_database.hpp"

namespace imucal::imu {

/// A signal of the protocol's DBC: indices into DbcDatabase::messages and that message's signals.
struct DbcSignalRef {
  int message = -1, signal = -1;
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
  std::vector<DbcSignalRef> fault, saturation, startup;
  struct ByteRange {
    int message = -1, first = 0, last = 0;  ///< bytes first..last of the message
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

/// Parses a protocol file's text; `path` names it and locates a relative DBC path.
ImuProtocolMap parse_protocol_map(const std::string& text, const std::string& path);
/// Reads and parses a protocol file (and the DBC file it names).
ImuProtocolMap read_protocol_map(const std::string& path);

}  // namespace imucal::imu
