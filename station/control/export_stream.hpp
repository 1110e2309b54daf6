#pragma once
// Streamed exports of the calibration history over the control socket (control_protocol.hpp,
// export with "stream": true). Each export runs in a thread of its own, with its own read-only
// connection to the history database (SQLite in WAL mode: the daemon keeps writing meanwhile), and
// writes straight to the client's socket in frames of at most kFrameBytes. Neither the server's
// poll loop nor the daemon's memory sees the export's size: 2·10⁵ rows are ~270 MB of CSV.
//
// A client that goes away ends its export at the next frame (EPIPE), one that stops reading is
// dropped after send_timeout; the daemon goes on either way. At most max_concurrent exports run;
// one more is refused (busy) without touching its connection
// (station/control/connection_threads.hpp).
#include <chrono>
#include <cstddef>
#include <string>

#include "station/control/connection_threads.hpp"
#include "station/control/control_protocol.hpp"

namespace imucal::station::control {

class ExportStreams {
 public:
  static constexpr std::size_t kFrameBytes = 64 * 1024;

  ExportStreams(std::string database_path, std::size_t max_concurrent,
                std::chrono::milliseconds send_timeout);
  ExportStreams(const ExportStreams&) = delete;
  ExportStreams& operator=(const ExportStreams&) = delete;

  /// Streams the export `request` asks for (validated by parse_request) to the connection `fd`,
  /// which it takes over and closes when done. `user` is for the log. ControlError(busy) when
  /// max_concurrent exports run already; `fd` is then left to the caller.
  void start(int fd, const Request& request, const std::string& user);
  /// Ends every export (their connections shut down mid-frame) and joins the threads.
  void stop_all() { threads_.stop_all(); }
  /// Exports running now.
  std::size_t active() const { return threads_.active(); }

 private:
  std::string database_path_;
  std::chrono::milliseconds send_timeout_;
  ConnectionThreads threads_;
};

}  // namespace imucal::station::control
