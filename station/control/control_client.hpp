#pragma once
// A client of the control socket (control_protocol.hpp): connect, send one request line, read the
// reply with a timeout. Used by stationctl and by the tests. Not thread-safe (one per thread).
#include <chrono>
#include <cstdint>
#include <functional>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>
#include <string_view>

#include "station/control/control_protocol.hpp"

namespace imucal::station::control {

class ControlClientError : public std::runtime_error {
 public:
  enum class Kind {
    kUnreachable,   ///< connect failed: no socket file, nobody listening
    kNoPermission,  ///< connect refused by the socket file's mode (not owner, not in its group)
    kTimeout,       ///< no (complete) reply within the timeout
    kClosed,        ///< the daemon closed the connection
    kIo,            ///< another socket error
    kProtocol,      ///< the reply is not a protocol reply (or answers another id)
  };
  ControlClientError(Kind kind, const std::string& message)
      : std::runtime_error(message), kind_(kind) {}
  Kind kind() const { return kind_; }

 private:
  Kind kind_;
};

class ControlClient {
 public:
  /// Connects; ControlClientError(kUnreachable) naming the path and the reason otherwise.
  explicit ControlClient(std::string socket_path,
                         std::chrono::milliseconds connect_timeout = std::chrono::seconds(2));
  ~ControlClient();
  ControlClient(const ControlClient&) = delete;
  ControlClient& operator=(const ControlClient&) = delete;
  /// Movable, so that a follower whose daemon went away and came back can take a new connection
  /// in place of the dead one (stationctl run start --wait); the moved-from client is closed.
  ControlClient(ControlClient&& other) noexcept;
  ControlClient& operator=(ControlClient&& other) noexcept;

  /// Sends {"id":next,"cmd":command,"args":args} and returns the reply with that id (a reply
  /// with another id is a kProtocol error). An error reply is returned, not thrown.
  Reply call(const std::string& command, const nlohmann::json& args = nlohmann::json::object(),
             std::chrono::milliseconds timeout = std::chrono::seconds(30));

  /// A streamed request (export with "stream": true, control_protocol.hpp): hands the export's
  /// bytes to `sink` frame by frame as they arrive (at most a frame is held) and returns the final
  /// reply (rows) — or the error reply, which may come before any bytes or after some. `timeout`
  /// applies to each wait for data (a stalled daemon), not to the whole export.
  Reply call_streamed(const std::string& command, const nlohmann::json& args,
                      const std::function<void(std::string_view)>& sink,
                      std::chrono::milliseconds timeout = std::chrono::seconds(30));

  /// Raw access for tests: write bytes as they are; read one line (without '\n').
  void send_raw(std::string_view bytes);
  std::string read_line(std::chrono::milliseconds timeout);
  /// True if the daemon closed the connection within `timeout` (buffered lines are discarded).
  bool closed_by_peer(std::chrono::milliseconds timeout);

  const std::string& socket_path() const { return path_; }
  int fd() const { return fd_; }

 private:
  Reply read_reply(std::int64_t id, std::chrono::milliseconds timeout);
  /// Exactly n bytes to sink (buffered ones first, then straight from the socket).
  void read_exact(std::size_t n, const std::function<void(std::string_view)>& sink,
                  std::chrono::milliseconds timeout);
  /// recv into buf by the deadline; the byte count (> 0), or throws (closed, timeout, error).
  std::size_t receive(char* buf, std::size_t size, std::chrono::steady_clock::time_point deadline,
                      std::chrono::milliseconds timeout);

  std::string path_;
  int fd_ = -1;
  std::int64_t next_id_ = 1;
  std::string in_;
};

}  // namespace imucal::station::control
