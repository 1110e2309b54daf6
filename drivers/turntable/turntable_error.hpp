#pragma once
// Typed errors of the turntable driver. All derive from TurntableError, whose kind() allows a switch;
// catch the derived type where the reaction differs (a fault needs clear_fault, a link error a
// reconnect or an abort, ...).
#include <cstdint>
#include <stdexcept>
#include <string>

namespace imucal::drivers::turntable {

enum class ErrorKind {
  kLink,             ///< link down and reconnection gave up (or connect failed)
  kTimeout,          ///< every attempt of one request timed out (the link is then re-opened)
  kBadResponse,      ///< malformed/mismatched replies on every attempt, or nonsense values
  kModbusException,  ///< the device answered with a Modbus exception (illegal address, ...)
  kAckTimeout,       ///< the table did not echo the command's sequence number in time
  kRejected,         ///< the table acknowledged the command with a non-zero result
  kFault,            ///< the table reports a latched fault
  kEstop,            ///< the e-stop circuit is open
  kHeartbeat,        ///< the PLC heartbeat stopped changing (program hung)
  kMoveTimeout,      ///< in-position (or standstill, or homed) not reached in time
  kAborted,          ///< request_abort() was called during a wait
  kInvalidArgument,  ///< non-finite target, non-positive rate, ...
};

const char* to_string(ErrorKind kind);

class TurntableError : public std::runtime_error {
 public:
  TurntableError(ErrorKind kind, const std::string& message) : std::runtime_error(message), kind_(kind) {}
  ErrorKind kind() const { return kind_; }

 private:
  ErrorKind kind_;
};

#define IMUCAL_TURNTABLE_ERROR(Name, Kind)                                                   \
  class Name : public TurntableError {                                                       \
   public:                                                                                   \
    explicit Name(const std::string& message) : TurntableError(ErrorKind::Kind, message) {} \
  };
IMUCAL_TURNTABLE_ERROR(LinkError, kLink)
IMUCAL_TURNTABLE_ERROR(RequestTimeoutError, kTimeout)
IMUCAL_TURNTABLE_ERROR(BadResponseError, kBadResponse)
IMUCAL_TURNTABLE_ERROR(ModbusExceptionError, kModbusException)
IMUCAL_TURNTABLE_ERROR(AckTimeoutError, kAckTimeout)
IMUCAL_TURNTABLE_ERROR(EstopError, kEstop)
IMUCAL_TURNTABLE_ERROR(HeartbeatError, kHeartbeat)
IMUCAL_TURNTABLE_ERROR(MoveTimeoutError, kMoveTimeout)
IMUCAL_TURNTABLE_ERROR(AbortedError, kAborted)
IMUCAL_TURNTABLE_ERROR(InvalidArgumentError, kInvalidArgument)
#undef IMUCAL_TURNTABLE_ERROR

/// The table refused a command; result() is its ack_result (table-specific reason).
class CommandRejectedError : public TurntableError {
 public:
  CommandRejectedError(const std::string& message, uint16_t result)
      : TurntableError(ErrorKind::kRejected, message), result_(result) {}
  uint16_t result() const { return result_; }

 private:
  uint16_t result_;
};

/// The table latched a fault; fault_code() is its fault-code register.
class TableFaultError : public TurntableError {
 public:
  TableFaultError(const std::string& message, uint16_t fault_code)
      : TurntableError(ErrorKind::kFault, message), fault_code_(fault_code) {}
  uint16_t fault_code() const { return fault_code_; }

 private:
  uint16_t fault_code_;
};

}  // namespace imucal::drivers::turntable
