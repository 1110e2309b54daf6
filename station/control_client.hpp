#pragma once
// A client of the control socket (control_protocol.hpp): connect, send one request line, read the
// reply with a timeout. Used by stationctl and by the tests. Not thread-safe (one per thread).
#include <chrono>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>
#include <string_view>

#include "station/control_protocol.hpp"

namespace imucal::station {

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

  /// Sends {"id":next,"cmd":command,"args":args} and returns the reply with that id (a reply
  /// with another id is a kProtocol error). An error reply is returned, not thrown.
  Reply call(const std::string& command, const nlohmann::json& args = nlohmann::json::object(),
             std::chrono::milliseconds timeout = std::chrono::seconds(30));

  /// Raw access for tests: write bytes as they are; read one line (without '\n').
  void send_raw(std::string_view bytes);
  std::string read_line(std::chrono::milliseconds timeout);
  /// True if the daemon closed the connection within `timeout` (buffered lines are discarded).
  bool closed_by_peer(std::chrono::milliseconds timeout);

  const std::string& socket_path() const { return path_; }
  int fd() const { return fd_; }

 private:
  std::string path_;
  int fd_ = -1;
  std::int64_t next_id_ = 1;
  std::string in_;
};

}  // namespace imucal::station
