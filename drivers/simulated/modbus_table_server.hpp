#pragma once
#include <sys/select.h>
// Simulated turntable PLC behind a Modbus TCP server (libmodbus server API), for stationsim and
// tests.
//
// One server thread runs a select() loop over the listening socket and up to max_clients client
// sockets: each request is read with modbus_receive and answered with modbus_reply from a
// modbus_mapping that mirrors the TablePlc's register image (input registers refreshed from the PLC
// before every reply; holding registers handed to the PLC under the same lock hold as the reply to
// a write, so whoever has seen the confirmation finds the write in the PLC). Between requests the
// loop wakes every loop_period to advance the PLC.
//
// Time: the PLC clock follows a caller-provided TimeSource (seconds, monotonic); the server steps
// the PLC by the source's increments. ScaledRealTime is real time times a speed factor, so a
// station simulator can run the table accelerated. With no TimeSource the server never steps the
// PLC: the caller advances it through with_plc() (one physics clock shared with, e.g., an IMU
// simulator).
//
// Fault injection: drop_clients() (connection reset on every connected master), delay_replies()
// (replies held back, so masters time out), refuse_connections_for() (listening socket closed: new
// connects get ECONNREFUSED; re-opened on the same port afterwards).
#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <mutex>
#include <string>
#include <thread>

#include "drivers/simulated/table_plc.hpp"

typedef struct _modbus modbus_t;
struct _modbus_mapping_t;

namespace imucal::drivers::simulated {

/// PLC time in seconds; must not decrease.
using TimeSource = std::function<double()>;

/// Real (steady-clock) time since construction, multiplied by a speed factor.
class ScaledRealTime {
 public:
  explicit ScaledRealTime(double speed_factor = 1.0);
  double operator()() const;
  double speed_factor() const { return speed_; }

 private:
  double speed_;
  std::chrono::steady_clock::time_point start_;
};

struct ModbusTableServerConfig {
  std::string address = "127.0.0.1";  ///< IPv4 address to listen on
  int port = 0;                       ///< 0: let the kernel pick a free port; see port()
  int max_clients = 8;                ///< further connections are accepted and closed at once
  std::chrono::milliseconds loop_period{2};  ///< select() timeout = PLC step period when idle
};

struct ModbusTableServerStats {
  uint64_t requests = 0;        ///< requests received
  uint64_t write_requests = 0;  ///< of which writes (holding registers handed to the PLC)
  uint64_t accepted = 0;        ///< connections accepted
  uint64_t rejected_full = 0;   ///< connections closed because max_clients were connected
  uint64_t dropped = 0;         ///< connections closed by drop_clients()
  uint64_t delayed = 0;         ///< replies held back by delay_replies()
  int clients = 0;              ///< currently connected
};

class ModbusTableServer {
 public:
  ModbusTableServer(const TablePlcConfig& plc_config, ModbusTableServerConfig config,
                    TimeSource time = {});
  ~ModbusTableServer();
  ModbusTableServer(const ModbusTableServer&) = delete;
  ModbusTableServer& operator=(const ModbusTableServer&) = delete;

  /// Binds and listens, then starts the server thread. Throws std::runtime_error naming the address
  /// if the socket cannot be opened. port() is valid when it returns.
  void start();
  /// Stops the thread and closes every socket. Idempotent.
  void stop();
  bool running() const { return running_.load(); }
  int port() const { return port_.load(); }
  const ModbusTableServerConfig& config() const { return cfg_; }

  /// Runs f(TablePlc&) under the lock the server thread uses (inspect, inject faults, step).
  template <class F>
  auto with_plc(F&& f) {
    std::lock_guard<std::mutex> lock(mu_);
    return f(plc_);
  }

  // --- fault injection (thread-safe) ---
  /// Closes every connected client socket at the next loop iteration.
  void drop_clients() { drop_requested_.store(true); }
  /// Holds back each of the next `count` replies (count < 0: every reply until called with 0) by
  /// `delay`.
  void delay_replies(std::chrono::milliseconds delay, int count = -1);
  /// Closes the listening socket for `duration`; connects during that time are refused.
  void refuse_connections_for(std::chrono::milliseconds duration);

  ModbusTableServerStats stats() const;

 private:
  /// The serving loop's own state (clients, request buffer, refusal window), and run()'s named
  /// steps.
  struct Loop;
  void run();
  void apply_fault_knobs(Loop& loop);
  int wait_readable(Loop& loop, fd_set& readable);
  void accept_client(Loop& loop);
  void serve_request(Loop& loop, int fd);
  void open_listener();
  void close_listener();
  void advance_plc();  // mu_ held

  ModbusTableServerConfig cfg_;
  TimeSource time_;
  mutable std::mutex mu_;
  TablePlc plc_;
  double last_time_s_ = 0.0;

  modbus_t* ctx_ = nullptr;
  _modbus_mapping_t* mapping_ = nullptr;
  int listen_fd_ = -1;
  std::thread thread_;
  std::atomic<bool> running_{false};
  std::atomic<int> port_{0};

  std::atomic<bool> drop_requested_{false};
  std::atomic<int64_t> delay_ms_{0};
  std::atomic<int> delay_count_{0};
  std::atomic<int64_t> refuse_ms_{0};  ///< pending refusal request (ms), consumed by the loop

  struct {
    std::atomic<uint64_t> requests{0}, write_requests{0}, accepted{0}, rejected_full{0}, dropped{0},
        delayed{0};
    std::atomic<int> clients{0};
  } stats_;
};

}  // namespace imucal::drivers::simulated
