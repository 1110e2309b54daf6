#pragma once
// One classic CAN frame as the drivers handle it, and the same frame with its receive timestamp.
//
// The identifier word uses the Linux SocketCAN layout (linux/can.h) so that frames pass unchanged
// between SocketCAN, the unixcan transport (which carries `struct can_frame` records) and candump
// logs:
//   bits 0-28  identifier (11-bit standard or 29-bit extended)
//   bit 29     kCanErrFlag  error frame (bus/controller error, delivered by CAN_RAW_ERR_FILTER)
//   bit 30     kCanRtrFlag  remote transmission request
//   bit 31     kCanEffFlag  29-bit extended identifier
// Only classic CAN (at most 8 data bytes) is supported; CAN FD is optional in ARCHITECTURE §4 and
// unused.
#include <array>
#include <cstdint>

namespace imucal::drivers::imu {

constexpr uint32_t kCanEffFlag = 0x80000000U;
constexpr uint32_t kCanRtrFlag = 0x40000000U;
constexpr uint32_t kCanErrFlag = 0x20000000U;
constexpr uint32_t kCanSffMask = 0x000007FFU;
constexpr uint32_t kCanEffMask = 0x1FFFFFFFU;
constexpr uint8_t kCanMaxDataLength = 8;
/// Error classes in an error frame's identifier (linux/can/error.h): the controller went bus-off
/// (CAN_ERR_BUSOFF), controller problems such as error-passive (CAN_ERR_CRTL), protocol violations
/// (CAN_ERR_PROT), and the controller restarted after bus-off (CAN_ERR_RESTARTED).
constexpr uint32_t kCanErrCrtl = 0x00000004U;
constexpr uint32_t kCanErrProt = 0x00000008U;
constexpr uint32_t kCanErrBusOff = 0x00000040U;
constexpr uint32_t kCanErrRestarted = 0x00000100U;

struct CanFrame {
  uint32_t can_id = 0;             ///< identifier + flags (SocketCAN layout, see above)
  uint8_t len = 0;                 ///< data length 0..8
  std::array<uint8_t, 8> data{};   ///< bytes beyond len are zero

  bool is_extended() const { return (can_id & kCanEffFlag) != 0; }
  bool is_remote() const { return (can_id & kCanRtrFlag) != 0; }
  bool is_error() const { return (can_id & kCanErrFlag) != 0; }
  /// The bare identifier without flag bits.
  uint32_t id() const { return can_id & (is_extended() ? kCanEffMask : kCanSffMask); }

  friend bool operator==(const CanFrame& a, const CanFrame& b) {
    return a.can_id == b.can_id && a.len == b.len && a.data == b.data;
  }
  friend bool operator!=(const CanFrame& a, const CanFrame& b) { return !(a == b); }
};

/// A frame with the time it was received: CLOCK_REALTIME nanoseconds since the Unix epoch (the
/// kernel's SO_TIMESTAMP for sockets, microsecond resolution; the log's timestamp for candump).
struct ReceivedFrame {
  CanFrame frame;
  int64_t rx_time_ns = 0;
};

/// Now on the clock of ReceivedFrame::rx_time_ns (CLOCK_REALTIME, ns).
int64_t receive_clock_now_ns();

}  // namespace imucal::drivers::imu
