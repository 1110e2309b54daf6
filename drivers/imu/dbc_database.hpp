#pragma once
// A DBC file (the Vector CAN database format, in which CAN protocols are already written) as the
// station reads it (issue #27): messages with their identifier (11- or 29-bit), length (classic
// 0-8 or a CAN FD length up to 64), and signals with start bit, length, byte order, sign, value
// type, factor, offset, range, unit and simple multiplexing (one multiplexor per message, a signal
// present for one multiplexor value). What the station does not need — nodes' attributes, comments,
// value tables beyond a signal's own value descriptions, environment variables — is read past.
//
// Bit numbering is the DBC's: bit i is bit (i mod 8) of byte (i / 8). An Intel (little-endian, @1)
// signal's start bit is its least significant bit and it grows towards higher bits; a Motorola
// (big-endian, @0) signal's start bit is its most significant bit and it proceeds to the next
// lower bit of the same byte, then from bit 7 of the next byte ("sawtooth" order).
//
// Errors are std::invalid_argument "FILE:LINE: what": a malformed statement, a duplicate message
// identifier or signal name, a signal beyond its message, of length 0 or above 64, with a factor of
// 0, two signals that share a bit while both can be present (the same multiplexor value, or either
// one not multiplexed), extended multiplexing (not supported), a length CAN FD does not have.
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace imucal::drivers::imu {

struct DbcSignal {
  enum class ByteOrder { kIntel, kMotorola };
  enum class ValueType { kInteger, kFloat32, kFloat64 };
  std::string name;
  int start_bit = 0;  ///< DBC numbering (see the header)
  int length = 1;     ///< bits, 1..64 (32 for float32, 64 for float64)
  ByteOrder order = ByteOrder::kIntel;
  bool is_signed = false;
  ValueType type = ValueType::kInteger;
  double factor = 1.0, offset = 0.0;  ///< physical = raw × factor + offset
  double minimum = 0.0, maximum = 0.0;
  std::string unit;
  bool is_multiplexor = false;
  std::optional<int64_t> multiplex_value;      ///< present only when the multiplexor has this value
  std::map<int64_t, std::string> value_names;  ///< VAL_ descriptions
  int line = 0;                                ///< where it is defined (for errors)
};

struct DbcMessage {
  uint32_t id = 0;  ///< bare identifier (no flag bits)
  bool extended = false;
  bool fd = false;  ///< CAN FD (a length above 8, or VFrameFormat says so)
  std::string name;
  int length = 8;  ///< bytes
  std::string transmitter;
  std::vector<DbcSignal> signals;
  int line = 0;

  const DbcSignal* signal(const std::string& name) const;
  const DbcSignal* multiplexor() const;
};

struct DbcDatabase {
  std::string path;  ///< as given to the parser (for messages)
  std::string version;
  std::vector<std::string> nodes;
  std::vector<DbcMessage> messages;

  const DbcMessage* message(const std::string& name) const;
  const DbcMessage* message(uint32_t id, bool extended) const;
};

/// Parses DBC text; `path` names it in errors. Throws std::invalid_argument "path:line: what".
DbcDatabase parse_dbc(const std::string& text, const std::string& path);
/// Reads and parses a file (a file that cannot be read: std::invalid_argument naming it).
DbcDatabase read_dbc(const std::string& path);

/// The text of a small regular file (a DBC or protocol file): std::invalid_argument naming it and
/// `what` when it cannot be read, is not a regular file (a device, a pipe: never read to its end)
/// or is larger than 16 MiB.
std::string read_small_text_file(const std::string& path, const std::string& what);

}  // namespace imucal::drivers::imu
