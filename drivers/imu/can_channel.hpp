#pragma once
// CanChannel: one fd-based interface to a CAN bus, whatever carries it (ARCHITECTURE §4). Like
// mavlink-router's Pollable, a channel only moves frames: it exposes fd() for the caller's
// poll/epoll loop and non-blocking read()/write(); protocol logic (imu_codec.hpp) lives elsewhere.
//
// Transports, selected by the URI given to CanChannel::open():
//   socketcan:IFACE  raw CAN_RAW socket on a kernel CAN interface (can0, vcan0): SO_TIMESTAMP
//   receive
//                    times, error frames (CAN_RAW_ERR_FILTER = all classes) delivered as frames
//                    with kCanErrFlag, SO_RXQ_OVFL kernel drop counter -> counters().rx_overflow.
//                    A kernel without AF_CAN makes open() throw a message saying so.
//   unixcan:PATH     AF_UNIX SOCK_SEQPACKET socket carrying one `struct can_frame` (16 bytes) per
//                    record, read and written by the same code as SocketCAN (recvmmsg with
//                    SO_TIMESTAMP / sendmmsg). CanOpenOptions::listen = true creates PATH and acts
//                    as the bus: it accepts any number of peers, delivers what any peer writes and
//                    writes every frame to all peers (the simulator's side); otherwise the channel
//                    connects to PATH (the daemon's side).
//   candump:FILE     replay of a candump log file (candump_log.hpp): each frame's receive time is
//   the
//                    logged time. Read as fast as the caller reads, or paced at the logged rate ×
//                    CanOpenOptions::replay_speed (fd() is then a timerfd).
//
// Counters are cumulative for the channel's life. read() never blocks; wait_readable()
// is a convenience over poll(2) on fd(); write() waits only if
// CanOpenOptions::write_timeout_ms > 0.
#include <cstddef>
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "drivers/imu/can_frame.hpp"

namespace imucal::drivers::imu {

/// Failure to open or use a channel; what() names the URI and the system error.
class CanChannelError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct CanChannelCounters {
  uint64_t rx_frames = 0;        ///< frames returned by read() (error frames included)
  uint64_t rx_error_frames = 0;  ///< of which error frames (kCanErrFlag)
  uint64_t rx_overflow = 0;      ///< frames the kernel dropped on a full receive queue (SO_RXQ_OVFL)
  uint64_t rx_malformed = 0;     ///< records of the wrong size, truncated last log line
  uint64_t tx_frames = 0;        ///< frames accepted by write()
  uint64_t tx_overflow = 0;      ///< frames not sent because a transmit queue was full (per peer)
  uint64_t peers_connected = 0;  ///< unixcan listener: peers accepted so far
};

struct CanOpenOptions {
  /// unixcan: true = create PATH and accept peers (the bus side); false = connect to PATH.
  bool listen = false;
  /// candump: 0 = frames are readable at once; s > 0 = frame k becomes readable at
  /// open time + (t_k - t_0) / s.
  double replay_speed = 0.0;
  /// Socket buffer request (SO_SNDBUF and SO_RCVBUF, bytes; the kernel caps it at
  /// net.core.[wr]mem_max): a deep queue lets a receiver stall briefly without losing frames.
  int socket_buffer_bytes = 4 << 20;
  /// Writes: how long write() may wait for room in a full transmit queue (per peer) before it counts
  /// the rest as tx_overflow. 0 = never wait, as a saturated bus loses frames (the default);
  /// > 0 = lossless back-pressure for simulators and benchmarks that produce faster than real time.
  int write_timeout_ms = 0;
  /// Interface name written in candump logs for frames of this channel (candump: read from the log).
  std::string log_interface = "can0";
};

class CanChannel {
 public:
  /// Opens a channel from "socketcan:IFACE", "unixcan:PATH" or "candump:FILE".
  /// Throws CanChannelError with the URI and the reason (unknown scheme, missing file, no AF_CAN...).
  static std::unique_ptr<CanChannel> open(const std::string& uri, const CanOpenOptions& options = {});

  /// Two connected unixcan channels (socketpair(2)), for in-process simulators and tests.
  static std::pair<std::unique_ptr<CanChannel>, std::unique_ptr<CanChannel>> unix_pair(
      const CanOpenOptions& options = {});

  virtual ~CanChannel() = default;
  CanChannel(const CanChannel&) = delete;
  CanChannel& operator=(const CanChannel&) = delete;

  /// The descriptor to poll for readability (POLLIN) in the caller's event loop.
  virtual int fd() const = 0;
  /// Appends the frames available now (at most max_frames) to out; returns how many. Never blocks.
  virtual std::size_t read(std::vector<ReceivedFrame>& out, std::size_t max_frames = 256) = 0;
  /// Sends frames in order; returns how many were accepted. Waits for room in a full transmit queue
  /// at most CanOpenOptions::write_timeout_ms (default: not at all); frames still refused are counted
  /// in tx_overflow. For the unixcan listener the return value is `count` (the frames are on the bus)
  /// and a peer's refusals count in tx_overflow. Throws CanChannelError on a read-only
  /// channel (candump) or a dead connection.
  virtual std::size_t write(const CanFrame* frames, std::size_t count) = 0;
  bool write(const CanFrame& frame) { return write(&frame, 1) == 1; }
  /// True once no frame can ever arrive again (end of a candump log, unixcan peer closed).
  virtual bool at_end() const = 0;

  /// poll(2) on fd() for POLLIN; true if readable within timeout_ms (-1 = forever).
  bool wait_readable(int timeout_ms) const;

  const CanChannelCounters& counters() const { return counters_; }
  const std::string& uri() const { return uri_; }
  /// Interface name for candump logs (CanOpenOptions::log_interface, or the socketcan interface).
  const std::string& interface_name() const { return interface_name_; }

 protected:
  CanChannel(std::string uri, std::string interface_name)
      : uri_(std::move(uri)), interface_name_(std::move(interface_name)) {}
  CanChannelCounters counters_;

 private:
  std::string uri_;
  std::string interface_name_;
};

}  // namespace imucal::drivers::imu
