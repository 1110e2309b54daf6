#include "station/daemon/sd_notify.hpp"

#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <cerrno>
#include <cstddef>
#include <cstdlib>
#include <cstring>

namespace imucal::station::daemon {

SdNotifier::SdNotifier(std::string socket, std::optional<std::chrono::microseconds> watchdog_usec)
    : socket_(std::move(socket)), watchdog_usec_(watchdog_usec) {}

namespace {

std::optional<unsigned long long> parse_unsigned(const char* text) {
  if (!text || !*text) return std::nullopt;
  errno = 0;
  char* end = nullptr;
  const unsigned long long v = std::strtoull(text, &end, 10);
  if (errno != 0 || *end != '\0' || text[0] == '-') return std::nullopt;
  return v;
}

}  // namespace

SdNotifier SdNotifier::from_environment() {
  const char* sock = std::getenv("NOTIFY_SOCKET");
  std::optional<std::chrono::microseconds> wd;
  if (auto usec = parse_unsigned(std::getenv("WATCHDOG_USEC")); usec && *usec > 0) {
    const char* pid_text = std::getenv("WATCHDOG_PID");
    const auto pid = parse_unsigned(pid_text);
    const bool ours =
        !pid_text || !*pid_text || (pid && *pid == static_cast<unsigned long long>(getpid()));
    if (ours) wd = std::chrono::microseconds(static_cast<long long>(*usec));
  }
  return SdNotifier(sock ? sock : "", wd);
}

bool SdNotifier::notify(const std::string& state, std::string* error) const {
  if (socket_.empty()) {
    if (error) *error = "NOTIFY_SOCKET is not set";
    return false;
  }
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  if (socket_.size() >= sizeof(addr.sun_path) || (socket_[0] != '/' && socket_[0] != '@')) {
    if (error)
      *error = "NOTIFY_SOCKET \"" + socket_ + "\" is neither an absolute path nor '@'abstract";
    return false;
  }
  std::memcpy(addr.sun_path, socket_.data(), socket_.size());
  // Abstract namespace: leading NUL, and the address length counts exactly the name's bytes.
  if (socket_[0] == '@') addr.sun_path[0] = '\0';
  const socklen_t len = static_cast<socklen_t>(offsetof(sockaddr_un, sun_path) + socket_.size() +
                                               (socket_[0] == '@' ? 0 : 1));
  const int fd = ::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  if (fd < 0) {
    if (error) *error = std::string("socket: ") + std::strerror(errno);
    return false;
  }
  const ssize_t n = ::sendto(fd, state.data(), state.size(), MSG_NOSIGNAL,
                             reinterpret_cast<const sockaddr*>(&addr), len);
  const int err = errno;
  ::close(fd);
  if (n < 0 || static_cast<size_t>(n) != state.size()) {
    if (error) *error = "sendto " + socket_ + ": " + (n < 0 ? std::strerror(err) : "short write");
    return false;
  }
  return true;
}

bool SdNotifier::ready(const std::string& status_text) const {
  return notify(status_text.empty() ? "READY=1" : "READY=1\nSTATUS=" + status_text);
}
bool SdNotifier::status(const std::string& status_text) const {
  return notify("STATUS=" + status_text);
}
bool SdNotifier::watchdog() const { return notify("WATCHDOG=1"); }
bool SdNotifier::stopping() const { return notify("STOPPING=1"); }

std::optional<std::chrono::microseconds> SdNotifier::watchdog_interval() const {
  if (!watchdog_usec_) return std::nullopt;
  return *watchdog_usec_ / 2;
}

}  // namespace imucal::station::daemon
