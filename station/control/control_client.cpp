#include "station/control/control_client.hpp"

#include <errno.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <algorithm>
#include <cstring>
#include <thread>
#include <utility>

namespace imucal::station::control {

using Clock = std::chrono::steady_clock;
using Kind = ControlClientError::Kind;

namespace {

int remaining_ms(Clock::time_point deadline) {
  const auto left =
      std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count();
  return left < 0 ? 0 : static_cast<int>(left);
}

}  // namespace

ControlClient::ControlClient(std::string socket_path, std::chrono::milliseconds connect_timeout)
    : path_(std::move(socket_path)) {
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  if (path_.empty() || path_.size() >= sizeof addr.sun_path)
    throw ControlClientError(Kind::kUnreachable,
                             "control socket \"" + path_ + "\": not a usable socket path");
  std::memcpy(addr.sun_path, path_.c_str(), path_.size() + 1);
  const auto deadline = Clock::now() + connect_timeout;
  for (;;) {
    fd_ = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
    if (fd_ < 0)
      throw ControlClientError(Kind::kIo, std::string("socket(): ") + std::strerror(errno));
    if (::connect(fd_, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) == 0) return;
    const int err = errno;
    ::close(fd_);
    fd_ = -1;
    // A full listen backlog (EAGAIN) is a busy daemon, not an absent one: retry until the deadline.
    if (err == EACCES || err == EPERM)
      throw ControlClientError(Kind::kNoPermission,
                               "cannot connect to stationd at " + path_ + ": " +
                                   std::strerror(err) +
                                   " (the control socket admits its owner and the station's "
                                   "control group only)");
    if (err != EAGAIN || Clock::now() >= deadline)
      throw ControlClientError(
          Kind::kUnreachable, "cannot connect to stationd at " + path_ + ": " + std::strerror(err));
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
}

ControlClient::~ControlClient() {
  if (fd_ >= 0) ::close(fd_);
}

ControlClient::ControlClient(ControlClient&& other) noexcept
    : path_(std::move(other.path_)),
      fd_(std::exchange(other.fd_, -1)),
      next_id_(other.next_id_),
      in_(std::move(other.in_)) {}

ControlClient& ControlClient::operator=(ControlClient&& other) noexcept {
  if (this != &other) {
    if (fd_ >= 0) ::close(fd_);
    path_ = std::move(other.path_);
    fd_ = std::exchange(other.fd_, -1);
    next_id_ = other.next_id_;
    in_ = std::move(other.in_);
  }
  return *this;
}

void ControlClient::send_raw(std::string_view bytes) {
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t w = ::send(fd_, bytes.data() + done, bytes.size() - done, MSG_NOSIGNAL);
    if (w >= 0) {
      done += static_cast<std::size_t>(w);
      continue;
    }
    if (errno == EINTR) continue;
    if (errno == EAGAIN || errno == EWOULDBLOCK) {
      pollfd p{fd_, POLLOUT, 0};
      if (::poll(&p, 1, 30000) <= 0)
        throw ControlClientError(Kind::kTimeout, "control socket " + path_ + ": send timed out");
      continue;
    }
    if (errno == EPIPE || errno == ECONNRESET)
      throw ControlClientError(Kind::kClosed, "stationd closed the connection (" + path_ + ")");
    throw ControlClientError(Kind::kIo,
                             "control socket " + path_ + ": send: " + std::strerror(errno));
  }
}

std::size_t ControlClient::receive(char* buf, std::size_t size, Clock::time_point deadline,
                                   std::chrono::milliseconds timeout) {
  for (;;) {
    pollfd p{fd_, POLLIN, 0};
    const int n = ::poll(&p, 1, remaining_ms(deadline));
    if (n < 0) {
      if (errno == EINTR) continue;
      throw ControlClientError(Kind::kIo, std::string("poll: ") + std::strerror(errno));
    }
    if (n == 0)
      throw ControlClientError(Kind::kTimeout, "no reply from stationd at " + path_ + " within " +
                                                   std::to_string(timeout.count()) + " ms");
    const ssize_t r = ::recv(fd_, buf, size, 0);
    if (r == 0)
      throw ControlClientError(Kind::kClosed, "stationd closed the connection (" + path_ + ")");
    if (r < 0) {
      if (errno == EINTR || errno == EAGAIN || errno == EWOULDBLOCK) continue;
      if (errno == ECONNRESET)
        throw ControlClientError(Kind::kClosed, "stationd reset the connection (" + path_ + ")");
      throw ControlClientError(Kind::kIo, std::string("recv: ") + std::strerror(errno));
    }
    return static_cast<std::size_t>(r);
  }
}

std::string ControlClient::read_line(std::chrono::milliseconds timeout) {
  const auto deadline = Clock::now() + timeout;
  std::size_t scanned = 0;
  char buf[65536];
  for (;;) {
    const std::size_t nl = in_.find('\n', scanned);
    if (nl != std::string::npos) {
      if (nl + 1 == in_.size()) {  // the usual case: no copy of a large reply
        std::string line = std::move(in_);
        in_.clear();
        line.pop_back();
        return line;
      }
      std::string line = in_.substr(0, nl);
      in_.erase(0, nl + 1);
      return line;
    }
    scanned = in_.size();
    in_.append(buf, receive(buf, sizeof buf, deadline, timeout));
  }
}

void ControlClient::read_exact(std::size_t n, const std::function<void(std::string_view)>& sink,
                               std::chrono::milliseconds timeout) {
  const std::size_t buffered = std::min(n, in_.size());
  if (buffered > 0) {
    sink(std::string_view(in_).substr(0, buffered));
    in_.erase(0, buffered);
    n -= buffered;
  }
  char buf[65536];
  while (n > 0) {
    const std::size_t got = receive(buf, std::min(n, sizeof buf), Clock::now() + timeout, timeout);
    sink(std::string_view(buf, got));
    n -= got;
  }
}

bool ControlClient::closed_by_peer(std::chrono::milliseconds timeout) {
  const auto deadline = Clock::now() + timeout;
  char buf[65536];
  for (;;) {
    pollfd p{fd_, POLLIN, 0};
    const int n = ::poll(&p, 1, remaining_ms(deadline));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    const ssize_t r = ::recv(fd_, buf, sizeof buf, 0);
    if (r == 0) return true;
    if (r < 0) {
      if (errno == EINTR || errno == EAGAIN) continue;
      return true;  // reset
    }
  }
}

Reply ControlClient::call(const std::string& command, const nlohmann::json& args,
                          std::chrono::milliseconds timeout) {
  const std::int64_t id = next_id_++;
  send_raw(request_line(id, command, args));
  return read_reply(id, timeout);
}

Reply ControlClient::call_streamed(const std::string& command, const nlohmann::json& args,
                                   const std::function<void(std::string_view)>& sink,
                                   std::chrono::milliseconds timeout) {
  const std::int64_t id = next_id_++;
  send_raw(request_line(id, command, args));
  const Reply header = read_reply(id, timeout);
  if (!header.ok) return header;
  if (!header.result.is_object() || !header.result.value("stream", false))
    throw ControlClientError(Kind::kProtocol,
                             "stationd at " + path_ + ": " + command + " was not streamed");
  for (;;) {
    const std::string size_line = read_line(timeout);
    std::size_t n = 0;
    std::size_t used = 0;
    try {
      n = std::stoull(size_line, &used, 16);
    } catch (const std::exception&) {
      used = 0;
    }
    if (size_line.empty() || used != size_line.size())
      throw ControlClientError(Kind::kProtocol, "stationd at " + path_ +
                                                    ": a frame of the stream starts with \"" +
                                                    size_line.substr(0, 40) + "\"");
    if (n == 0) break;
    read_exact(n, sink, timeout);
  }
  return read_reply(id, timeout);
}

Reply ControlClient::read_reply(std::int64_t id, std::chrono::milliseconds timeout) {
  const std::string line = read_line(timeout);
  Reply r;
  try {
    r = parse_reply(line);
  } catch (const std::exception& e) {
    throw ControlClientError(Kind::kProtocol, "stationd at " + path_ + ": " + e.what());
  }
  if (!(r.id.is_number_integer() && r.id.get<std::int64_t>() == id) && !(r.id.is_null() && !r.ok))
    throw ControlClientError(Kind::kProtocol, "stationd at " + path_ + ": reply for id " +
                                                  r.id.dump() + ", expected " + std::to_string(id));
  return r;
}

}  // namespace imucal::station::control
