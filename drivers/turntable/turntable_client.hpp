#pragma once
// Modbus master for a PLC-driven two-axis turntable (ARCHITECTURE §4), over TCP or RTU (libmodbus).
//
// Link handling: libmodbus error recovery is NONE; errno is handled here. A timeout flushes the
// link and retries the request; a malformed or mismatched reply (e.g. a late reply to a request
// that had timed out) waits until the link is quiet, flushes and retries; a Modbus exception is
// reported at once; a link error (reset, refused, broken pipe, I/O error) closes the context and
// reconnects with exponential backoff (backoff_initial doubling up to backoff_max) until
// reconnect_give_up has passed, then throws LinkError. When every attempt of a request timed out
// the link is treated as dead: it is closed and the next request reconnects.
//
// Commands use the register map's handshake (register_map.hpp): targets and the command word with a
// fresh sequence number are written (in one request when the map makes them contiguous), then the
// input registers are polled until ack_seq echoes the sequence; a non-zero ack_result throws
// CommandRejectedError, no echo within ack_timeout throws AckTimeoutError. If the link was
// re-opened while waiting, the command is written again with the SAME sequence number (the table
// ignores a repeated sequence, so this cannot act twice).
//
// Safety: the table is commanded to stop on connect() (start-up, unless stop_on_connect is off),
// when a wait sees a fault, an e-stop, a stale heartbeat, a timeout or an abort request, and (best
// effort, without reconnecting) on destruction of a client that has commanded a move or homing. The
// daemon calls safe_stop() itself on shutdown.
//
// One commanding master per table: two clients sending commands at the same time can pick the same
// sequence number, and the table acts on only one of them. Read-only observers (status() only, with
// stop_on_connect off) may be connected in any number.
//
// Threading: one libmodbus context per client and one thread using it at a time (libmodbus contexts
// are not thread-safe). request_abort(), state() and counters() may be called from any thread.
#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "drivers/turntable/register_map.hpp"
#include "drivers/turntable/turntable_error.hpp"

typedef struct _modbus modbus_t;
namespace spdlog {
class logger;
}

namespace imucal::drivers::turntable {

/// Where the table is: "tcp:HOST:PORT" or "rtu:DEVICE:BAUD:FORMAT" with FORMAT like 8N1 / 8E1 /
/// 8O2.
struct Endpoint {
  enum class Kind { kTcp, kRtu };
  Kind kind = Kind::kTcp;
  std::string host = "127.0.0.1";
  int port = 502;
  std::string device;  ///< RTU serial device, e.g. /dev/ttyUSB0
  int baud = 19200;
  char parity = 'E';  ///< 'N', 'E' or 'O'
  int data_bits = 8;
  int stop_bits = 1;

  /// Parses the text form; throws std::invalid_argument naming the bad part.
  static Endpoint parse(const std::string& text);
  std::string to_string() const;
};

struct TurntableClientConfig {
  Endpoint endpoint;
  RegisterMap map = default_register_map();
  std::chrono::milliseconds response_timeout{250};  ///< per request
  int max_attempts = 3;                             ///< per request, for timeouts and bad replies
  std::chrono::milliseconds backoff_initial{50};    ///< first reconnect delay, doubled each failure
  std::chrono::milliseconds backoff_max{2000};
  std::chrono::milliseconds reconnect_give_up{10000};  ///< total reconnect time before LinkError
  std::chrono::milliseconds ack_timeout{1000};         ///< command -> ack_seq echo
  std::chrono::milliseconds poll_period{20};           ///< status polling in the wait_* calls
  std::chrono::milliseconds heartbeat_timeout{
      1000};  ///< heartbeat unchanged this long = stale = fault
  double position_tolerance_deg =
      0.01;                     ///< |actual - target| required on top of the in_position bit
  bool stop_on_connect = true;  ///< command a safe stop right after connecting (start-up)
  std::shared_ptr<spdlog::logger> logger;  ///< null: spdlog's default logger
};

/// One decoded snapshot of the input registers.
struct TableStatus {
  double outer_deg = 0.0, inner_deg = 0.0;
  double outer_rate_dps = 0.0, inner_rate_dps = 0.0;
  bool enabled = false, homed = false, moving = false, in_position = false, fault = false,
       estop = false;
  uint16_t fault_code = 0;
  uint16_t heartbeat = 0;
  bool heartbeat_stale = false;  ///< heartbeat unchanged for longer than heartbeat_timeout
  uint16_t ack_seq = 0, ack_result = 0;
};

/// Driver state as last observed (ros2_control-style lifecycle; PX4-style explicit enum).
enum class State {
  kDisconnected,  ///< no link: before connect(), after close(), or reconnection gave up
  kReconnecting,  ///< link lost; reopening with backoff
  kDisabled,      ///< link up; drives not enabled, no fault, no e-stop
  kReady,         ///< enabled, no profile running, not in position (after enable/stop, or settling)
  kMoving,        ///< a profile runs (move, home, or ramp-down after stop)
  kInPosition,    ///< at the last commanded target and settled
  kFault,         ///< fault latched, or heartbeat stale: needs clear_fault() + enable()
  kEstop,         ///< e-stop circuit open
};
const char* to_string(State s);

struct ClientCounters {
  uint64_t requests = 0;          ///< Modbus transactions attempted
  uint64_t timeouts = 0;          ///< transactions that timed out
  uint64_t bad_responses = 0;     ///< malformed/mismatched replies, nonsense values
  uint64_t exceptions = 0;        ///< Modbus exception replies
  uint64_t link_errors = 0;       ///< link failures seen (reset, refused, ...)
  uint64_t reconnects = 0;        ///< successful re-opens after a link loss
  uint64_t connect_failures = 0;  ///< failed connect attempts (each backoff step)
  uint64_t commands = 0;          ///< commands acknowledged as accepted
  uint64_t rejected = 0;          ///< commands acknowledged as rejected
  uint64_t heartbeat_stale = 0;   ///< transitions into "heartbeat stale"
};

class TurntableClient {
 public:
  explicit TurntableClient(TurntableClientConfig config);
  ~TurntableClient();
  TurntableClient(const TurntableClient&) = delete;
  TurntableClient& operator=(const TurntableClient&) = delete;

  /// Opens the link (retrying with backoff up to reconnect_give_up), learns the table's last
  /// sequence number, and commands a safe stop if stop_on_connect.
  void connect();
  /// Closes the link (no stop command).
  void close();
  bool connected() const { return ctx_ != nullptr; }

  /// Reads and decodes the input registers (one request); updates state() and heartbeat tracking.
  TableStatus status();

  void enable();
  void clear_fault();
  /// Commands homing and waits until homed and in position.
  TableStatus home(std::chrono::milliseconds timeout);
  /// Writes targets and rate, commands the move and waits for its acknowledgement (not for the
  /// motion).
  void move_to(double outer_deg, double inner_deg, double rate_dps);
  /// Waits until the table is in position at the last move_to target. On fault, e-stop, stale
  /// heartbeat, abort or timeout it commands a safe stop and throws the matching error.
  TableStatus wait_in_position(std::chrono::milliseconds timeout);
  /// Commands a stop (decelerate to standstill) and waits for its acknowledgement.
  void stop();
  /// Waits until no profile is running. Throws MoveTimeoutError.
  TableStatus wait_stopped(std::chrono::milliseconds timeout);
  /// stop() that never throws: logs and returns false if the stop could not be delivered.
  bool safe_stop() noexcept;

  /// Thread-safe: makes the current/next wait_* call stop the table and throw AbortedError.
  void request_abort() { abort_.store(true); }
  void clear_abort() { abort_.store(false); }

  State state() const { return state_.load(); }
  ClientCounters counters() const;
  const TurntableClientConfig& config() const { return cfg_; }

 private:
  struct Write {
    uint16_t address;
    std::vector<uint16_t> values;
  };

  bool open_once(std::string* why);
  void open_with_backoff(bool is_reconnect, const std::string& reason);
  /// AbortedError if request_abort() was called (checked between connection attempts).
  void throw_if_aborted(const char* what);
  void drop_link();
  template <class Op>
  int transact(const char* what, Op op);
  void flush_quiet();
  TableStatus read_status();
  void write_runs(std::vector<Write> writes, uint16_t command_address);
  TableStatus command(uint16_t code, const char* name, std::vector<Write> extra);
  TableStatus wait_for(std::chrono::milliseconds timeout, const char* what, bool need_homed);
  void check_safety(const TableStatus& s, const char* during);
  void update_state(const TableStatus& s);
  uint16_t take_seq();
  spdlog::logger& log() const;

  TurntableClientConfig cfg_;
  std::shared_ptr<spdlog::logger> logger_;
  modbus_t* ctx_ = nullptr;
  uint16_t next_seq_ = 1;
  std::optional<std::pair<double, double>>
      target_deg_;  ///< last accepted move target (outer, inner)

  std::optional<uint16_t> last_heartbeat_;
  std::chrono::steady_clock::time_point heartbeat_changed_at_{};
  bool heartbeat_was_stale_ = false;

  std::atomic<bool> abort_{false};
  std::atomic<State> state_{State::kDisconnected};
  struct AtomicCounters {
    std::atomic<uint64_t> requests{0}, timeouts{0}, bad_responses{0}, exceptions{0}, link_errors{0},
        reconnects{0}, connect_failures{0}, commands{0}, rejected{0}, heartbeat_stale{0};
  } n_;
  bool commanded_motion_ = false;  ///< a move/home was accepted: the destructor stops the table
  bool no_reconnect_ =
      false;  ///< set while destroying: a best-effort stop must not block on backoff
};

}  // namespace imucal::drivers::turntable
