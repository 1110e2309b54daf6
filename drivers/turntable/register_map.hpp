#pragma once
// Turntable Modbus register map: DATA, not code (ARCHITECTURE §4). Real tables differ, so every
// address, bit number, command code and the float word order comes from a TOML table in the station
// config; `register_map.example.toml` next to this header is the simulator's default map and
// `default_register_map()` returns the same values (a test keeps them equal).
//
// Addresses are 0-based PDU addresses (what goes on the wire; mbpoll's `-0`). A float32 field
// occupies two consecutive registers, a uint16 field one.
//
// Command/acknowledge handshake: the master writes `command` (a command code) and `command_seq` (a
// sequence number, never 0) in ONE write-multiple-registers request (so `command_seq` must directly
// follow `command`). The table acts once per new sequence number and then echoes it in the input
// register `ack_seq`, with `ack_result` = 0 for "accepted" or a non-zero, table-specific reason for
// "rejected". A move's targets and rate are written before, or in the same request as, the command.
#include <cstdint>
#include <stdexcept>
#include <string>
#include <string_view>

#include <toml++/toml.h>

#include "drivers/turntable/float_codec.hpp"

namespace imucal::drivers::turntable {

/// Holding registers (function 3 read, 16 write): what the master commands.
struct HoldingRegisters {
  uint16_t target_outer_deg = 0;  ///< float32, outer-axis target angle, deg
  uint16_t target_inner_deg = 2;  ///< float32, inner-axis target angle, deg
  uint16_t max_rate_dps = 4;      ///< float32, rate limit for the move, deg/s (both axes)
  uint16_t command = 6;           ///< uint16, command code (see CommandCodes)
  uint16_t command_seq = 7;       ///< uint16, sequence number; must be command + 1
  bool operator==(const HoldingRegisters& o) const;
};

/// Input registers (function 4): what the table reports.
struct InputRegisters {
  uint16_t actual_outer_deg = 0;  ///< float32, deg
  uint16_t actual_inner_deg = 2;  ///< float32, deg
  uint16_t rate_outer_dps = 4;    ///< float32, deg/s
  uint16_t rate_inner_dps = 6;    ///< float32, deg/s
  uint16_t status = 8;            ///< uint16, status bits (see StatusBits)
  uint16_t fault_code = 9;        ///< uint16, 0 = no fault
  uint16_t heartbeat = 10;        ///< uint16, counter the PLC increments while its program runs
  uint16_t ack_seq = 11;          ///< uint16, sequence number of the last command acted on
  uint16_t ack_result = 12;       ///< uint16, 0 = accepted, otherwise the table's rejection reason
  bool operator==(const InputRegisters& o) const;
};

/// Bit numbers (0 = LSB) inside the status register.
struct StatusBits {
  uint8_t enabled = 0;      ///< drives powered and under control
  uint8_t homed = 1;        ///< reference search done since power-up
  uint8_t moving = 2;       ///< a motion profile is running
  uint8_t in_position = 3;  ///< at the commanded target and settled
  uint8_t fault = 4;        ///< a fault latched (see fault_code); needs clear_fault + enable
  uint8_t estop = 5;        ///< emergency stop circuit open
  bool operator==(const StatusBits& o) const;
};

/// Values written to the command register. 0 is reserved for "no command".
struct CommandCodes {
  uint16_t enable = 1;
  uint16_t move = 2;
  uint16_t stop = 3;
  uint16_t home = 4;
  uint16_t clear_fault = 5;
  bool operator==(const CommandCodes& o) const;
};

struct RegisterMap {
  uint8_t unit_id = 1;                       ///< Modbus unit (slave) id
  WordOrder word_order = WordOrder::kABCD;   ///< float32 layout, see float_codec.hpp
  HoldingRegisters holding;
  InputRegisters input;
  StatusBits status_bits;
  CommandCodes commands;

  /// Number of holding / input registers from address 0 through the highest one used (<= 65536).
  int holding_extent() const;
  int input_extent() const;
  /// Lowest input register used (block reads start here).
  uint16_t input_first() const;

  bool operator==(const RegisterMap& o) const;
  bool operator!=(const RegisterMap& o) const { return !(*this == o); }
};

/// Bad register map. what() reads "ORIGIN:LINE: message".
class RegisterMapError : public std::runtime_error {
 public:
  RegisterMapError(const std::string& origin, int line, const std::string& message);
  int line() const { return line_; }

 private:
  int line_;
};

/// The simulator's map; equal to register_map.example.toml.
RegisterMap default_register_map();

/// Reads a map from a TOML table shaped like the [register_map] table of the example file (keys
/// `unit_id`, `word_order` and sub-tables `holding`, `input`, `status_bits`, `commands`; every key
/// required, unknown keys rejected). Checks: addresses fit in 16 bits, no two fields of one register
/// space overlap (a float32 takes two registers), command_seq == command + 1, status bits 0..15 and
/// distinct, command codes non-zero and distinct. `origin` names the file in error messages.
RegisterMap register_map_from_toml(const toml::table& register_map_table, const std::string& origin);

/// Parses TOML text whose top level holds a [register_map] table.
RegisterMap parse_register_map(std::string_view toml_text, const std::string& origin);
/// Reads a TOML file whose top level holds a [register_map] table.
RegisterMap load_register_map(const std::string& path);

/// One-line human description, e.g. for the start-up log.
std::string describe(const RegisterMap& map);

}  // namespace imucal::drivers::turntable
