#pragma once
// The daemon's side of systemd's notification protocol (sd_notify(3)), written here instead of
// linking libsystemd for it: one datagram of newline-separated "VAR=value" assignments sent to the
// AF_UNIX socket named by $NOTIFY_SOCKET — a path, or an abstract socket when it starts with '@'.
// Without $NOTIFY_SOCKET (not started by systemd with Type=notify) every call is a no-op that
// returns false, so the daemon runs the same way from a shell.
//
// Watchdog: with WatchdogSec= systemd sets $WATCHDOG_USEC (and $WATCHDOG_PID); the service must
// send WATCHDOG=1 more often than that. sd_watchdog_enabled(3) recommends half the interval, which
// is what watchdog_interval() returns.
#include <chrono>
#include <optional>
#include <string>

namespace imucal::station::daemon {

class SdNotifier {
 public:
  /// No socket: every notification is dropped.
  SdNotifier() = default;
  /// `socket` as in $NOTIFY_SOCKET ("" = disabled); `watchdog_usec` as in $WATCHDOG_USEC.
  SdNotifier(std::string socket, std::optional<std::chrono::microseconds> watchdog_usec);

  /// From $NOTIFY_SOCKET, $WATCHDOG_USEC and $WATCHDOG_PID (the watchdog is ours only if
  /// $WATCHDOG_PID is unset or equals getpid()). Malformed values disable the watchdog.
  static SdNotifier from_environment();

  bool enabled() const { return !socket_.empty(); }
  const std::string& socket() const { return socket_; }

  /// Sends `state` (e.g. "READY=1\nSTATUS=idle") as one datagram. false if disabled or the send
  /// failed (errno-based description in *error if given). Thread-safe (one socket per call).
  bool notify(const std::string& state, std::string* error = nullptr) const;

  bool ready(const std::string& status_text = {}) const;
  bool status(const std::string& status_text) const;
  bool watchdog() const;
  bool stopping() const;

  /// Half of $WATCHDOG_USEC, or nullopt if systemd expects no keep-alives.
  std::optional<std::chrono::microseconds> watchdog_interval() const;

 private:
  std::string socket_;
  std::optional<std::chrono::microseconds> watchdog_usec_;
};

}  // namespace imucal::station::daemon
