#include "drivers/imu/can_channel.hpp"

#include <fcntl.h>
#include <linux/can.h>
#include <linux/can/error.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <poll.h>
#include <sys/epoll.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/timerfd.h>
#include <sys/un.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <ctime>
#include <optional>

#include "drivers/imu/candump_log.hpp"

namespace imucal::drivers::imu {

int64_t receive_clock_now_ns() {
  timespec ts{};
  ::clock_gettime(CLOCK_REALTIME, &ts);
  return static_cast<int64_t>(ts.tv_sec) * 1000000000 + ts.tv_nsec;
}

namespace {

static_assert(sizeof(struct can_frame) == 16, "unixcan records are Linux struct can_frame");
static_assert(kCanEffFlag == CAN_EFF_FLAG && kCanRtrFlag == CAN_RTR_FLAG && kCanErrFlag == CAN_ERR_FLAG,
              "can_frame.hpp flags must match linux/can.h");
static_assert(kCanErrCrtl == CAN_ERR_CRTL && kCanErrProt == CAN_ERR_PROT &&
                  kCanErrBusOff == CAN_ERR_BUSOFF && kCanErrRestarted == CAN_ERR_RESTARTED,
              "can_frame.hpp error classes must match linux/can/error.h");

std::string errno_text() { return std::strerror(errno); }

int64_t monotonic_now_ns() {
  timespec ts{};
  ::clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<int64_t>(ts.tv_sec) * 1000000000 + ts.tv_nsec;
}

/// RAII file descriptor.
class Fd {
 public:
  Fd() = default;
  explicit Fd(int fd) : fd_(fd) {}
  ~Fd() { reset(); }
  Fd(Fd&& o) noexcept : fd_(o.release()) {}
  Fd& operator=(Fd&& o) noexcept {
    if (this != &o) {
      reset();
      fd_ = o.release();
    }
    return *this;
  }
  int get() const { return fd_; }
  int release() {
    const int f = fd_;
    fd_ = -1;
    return f;
  }
  void reset() {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
  }

 private:
  int fd_ = -1;
};

void set_int_option(int fd, int level, int name, int value, const std::string& uri, const char* what) {
  if (::setsockopt(fd, level, name, &value, sizeof value) != 0)
    throw CanChannelError(uri + ": cannot set " + what + ": " + errno_text());
}

/// Options common to SocketCAN and unixcan sockets: receive timestamps, kernel drop counter, buffers.
void configure_socket(int fd, const CanOpenOptions& options, const std::string& uri) {
  set_int_option(fd, SOL_SOCKET, SO_TIMESTAMP, 1, uri, "SO_TIMESTAMP");
  set_int_option(fd, SOL_SOCKET, SO_RXQ_OVFL, 1, uri, "SO_RXQ_OVFL");
  if (options.socket_buffer_bytes > 0) {
    // The kernel caps these at net.core.wmem_max/rmem_max; a smaller queue is not an error.
    set_int_option(fd, SOL_SOCKET, SO_SNDBUF, options.socket_buffer_bytes, uri, "SO_SNDBUF");
    set_int_option(fd, SOL_SOCKET, SO_RCVBUF, options.socket_buffer_bytes, uri, "SO_RCVBUF");
  }
}

CanFrame from_linux(const struct can_frame& lf) {
  CanFrame f;
  f.can_id = lf.can_id;
  f.len = lf.len > kCanMaxDataLength ? kCanMaxDataLength : lf.len;
  std::memcpy(f.data.data(), lf.data, f.len);
  return f;
}

struct can_frame to_linux(const CanFrame& f) {
  struct can_frame lf {};
  lf.can_id = f.can_id;
  lf.len = f.len > kCanMaxDataLength ? kCanMaxDataLength : f.len;
  std::memcpy(lf.data, f.data.data(), lf.len);
  return lf;
}

/// The one read path of SocketCAN and unixcan: batches of `struct can_frame` records with their
/// SO_TIMESTAMP and SO_RXQ_OVFL control messages (recvmmsg). Returns frames appended; sets `eof`
/// when the peer closed a unixcan connection.
std::size_t read_records(int fd, std::vector<ReceivedFrame>& out, std::size_t max_frames,
                         CanChannelCounters& counters, bool& eof, const std::string& uri) {
  constexpr std::size_t kBatch = 64;
  constexpr std::size_t kCtrl = CMSG_SPACE(sizeof(struct timeval)) + CMSG_SPACE(sizeof(uint32_t));
  std::array<struct can_frame, kBatch> frames{};
  std::array<struct iovec, kBatch> iov{};
  std::array<struct mmsghdr, kBatch> msgs{};
  alignas(struct cmsghdr) std::array<std::array<char, kCtrl>, kBatch> ctrl{};
  std::size_t got = 0;
  while (got < max_frames && !eof) {
    const std::size_t want = std::min(kBatch, max_frames - got);
    for (std::size_t i = 0; i < want; ++i) {
      iov[i] = {&frames[i], sizeof(struct can_frame)};
      msgs[i] = {};
      msgs[i].msg_hdr.msg_iov = &iov[i];
      msgs[i].msg_hdr.msg_iovlen = 1;
      msgs[i].msg_hdr.msg_control = ctrl[i].data();
      msgs[i].msg_hdr.msg_controllen = kCtrl;
    }
    const int n = ::recvmmsg(fd, msgs.data(), static_cast<unsigned>(want), MSG_DONTWAIT, nullptr);
    if (n < 0) {
      if (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR) break;
      if (errno == ECONNRESET) {
        eof = true;
        break;
      }
      throw CanChannelError(uri + ": receive failed: " + errno_text());
    }
    if (n == 0) break;
    const int64_t fallback_ns = receive_clock_now_ns();
    for (int i = 0; i < n; ++i) {
      const mmsghdr& m = msgs[static_cast<std::size_t>(i)];
      if (m.msg_len == 0) {  // SOCK_SEQPACKET end of file: the peer closed
        eof = true;
        break;
      }
      ReceivedFrame rf;
      rf.rx_time_ns = fallback_ns;
      for (cmsghdr* c = CMSG_FIRSTHDR(&m.msg_hdr); c; c = CMSG_NXTHDR(const_cast<msghdr*>(&m.msg_hdr), c)) {
        if (c->cmsg_level != SOL_SOCKET) continue;
        if (c->cmsg_type == SCM_TIMESTAMP) {
          struct timeval tv {};
          std::memcpy(&tv, CMSG_DATA(c), sizeof tv);
          rf.rx_time_ns = static_cast<int64_t>(tv.tv_sec) * 1000000000 + static_cast<int64_t>(tv.tv_usec) * 1000;
        } else if (c->cmsg_type == SO_RXQ_OVFL) {
          uint32_t dropped = 0;  // cumulative count of the socket's life
          std::memcpy(&dropped, CMSG_DATA(c), sizeof dropped);
          if (dropped > counters.rx_overflow) counters.rx_overflow = dropped;
        }
      }
      if (m.msg_len != sizeof(struct can_frame) || (m.msg_hdr.msg_flags & MSG_TRUNC) ||
          frames[static_cast<std::size_t>(i)].len > kCanMaxDataLength) {
        ++counters.rx_malformed;
        continue;
      }
      rf.frame = from_linux(frames[static_cast<std::size_t>(i)]);
      if (rf.frame.is_error()) ++counters.rx_error_frames;
      ++counters.rx_frames;
      out.push_back(rf);
      ++got;
    }
    if (static_cast<std::size_t>(n) < want) break;
  }
  return got;
}

bool poll_fd(int fd, short events, int timeout_ms) {
  pollfd p{fd, events, 0};
  for (;;) {
    const int r = ::poll(&p, 1, timeout_ms);
    if (r < 0 && errno == EINTR) continue;
    return r > 0 && (p.revents & (events | POLLHUP | POLLERR));
  }
}

/// The one write path: sendmmsg without blocking. Returns frames accepted; sets `dead` if the peer
/// is gone. Refused frames (queue full) are not counted here; callers count them.
std::size_t write_records(int fd, const CanFrame* frames, std::size_t count, bool& dead,
                          const std::string& uri, int timeout_ms) {
  constexpr std::size_t kBatch = 64;
  std::array<struct can_frame, kBatch> lf{};
  std::array<struct iovec, kBatch> iov{};
  std::array<struct mmsghdr, kBatch> msgs{};
  std::size_t sent = 0;
  while (sent < count) {
    const std::size_t want = std::min(kBatch, count - sent);
    for (std::size_t i = 0; i < want; ++i) {
      lf[i] = to_linux(frames[sent + i]);
      iov[i] = {&lf[i], sizeof(struct can_frame)};
      msgs[i] = {};
      msgs[i].msg_hdr.msg_iov = &iov[i];
      msgs[i].msg_hdr.msg_iovlen = 1;
    }
    const int n = ::sendmmsg(fd, msgs.data(), static_cast<unsigned>(want), MSG_DONTWAIT | MSG_NOSIGNAL);
    if (n < 0) {
      if (errno == EINTR) continue;
      if (errno == EAGAIN || errno == EWOULDBLOCK || errno == ENOBUFS) {
        if (timeout_ms > 0 && poll_fd(fd, POLLOUT, timeout_ms)) continue;
        break;
      }
      if (errno == EPIPE || errno == ECONNRESET || errno == ENOTCONN) {
        dead = true;
        break;
      }
      throw CanChannelError(uri + ": send failed: " + errno_text());
    }
    sent += static_cast<std::size_t>(n);
    if (static_cast<std::size_t>(n) < want && timeout_ms <= 0) break;
  }
  return sent;
}

// --------------------------------------------------------------------- socketcan / unixcan peers

/// A socket whose records are `struct can_frame`: SocketCAN raw sockets and connected unixcan sockets.
class RecordSocketChannel final : public CanChannel {
 public:
  RecordSocketChannel(std::string uri, std::string iface, Fd fd, int write_timeout_ms)
      : CanChannel(std::move(uri), std::move(iface)), fd_(std::move(fd)), write_timeout_ms_(write_timeout_ms) {}
  int fd() const override { return fd_.get(); }
  std::size_t read(std::vector<ReceivedFrame>& out, std::size_t max_frames) override {
    return read_records(fd_.get(), out, max_frames, counters_, eof_, uri());
  }
  std::size_t write(const CanFrame* frames, std::size_t count) override {
    bool dead = false;
    const std::size_t sent = write_records(fd_.get(), frames, count, dead, uri(), write_timeout_ms_);
    if (dead) {
      eof_ = true;
      throw CanChannelError(uri() + ": peer closed the connection");
    }
    counters_.tx_frames += sent;
    counters_.tx_overflow += count - sent;
    return sent;
  }
  bool at_end() const override { return eof_; }

 private:
  Fd fd_;
  int write_timeout_ms_;
  bool eof_ = false;
};

std::unique_ptr<CanChannel> open_socketcan(const std::string& uri, const std::string& iface,
                                           const CanOpenOptions& options) {
  if (iface.size() >= IFNAMSIZ)
    throw CanChannelError(uri + ": interface name longer than " + std::to_string(IFNAMSIZ - 1) + " characters");
  Fd s(::socket(PF_CAN, SOCK_RAW | SOCK_CLOEXEC, CAN_RAW));
  if (s.get() < 0) {
    const bool no_can = errno == EAFNOSUPPORT || errno == EPROTONOSUPPORT;
    throw CanChannelError(uri + ": cannot create a CAN_RAW socket: " + errno_text() +
                          (no_can ? " (this kernel has no SocketCAN support: load the can and can_raw "
                                    "modules, or use a unixcan: or candump: channel)"
                                  : ""));
  }
  struct ifreq ifr {};
  std::memcpy(ifr.ifr_name, iface.c_str(), iface.size());
  if (::ioctl(s.get(), SIOCGIFINDEX, &ifr) != 0)
    throw CanChannelError(uri + ": no CAN interface '" + iface + "': " + errno_text());
  // All error classes: bus-off, controller problems, lost arbitration... arrive as error frames.
  const can_err_mask_t err_mask = CAN_ERR_MASK;
  if (::setsockopt(s.get(), SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &err_mask, sizeof err_mask) != 0)
    throw CanChannelError(uri + ": cannot set CAN_RAW_ERR_FILTER: " + errno_text());
  configure_socket(s.get(), options, uri);
  struct sockaddr_can addr {};
  addr.can_family = AF_CAN;
  addr.can_ifindex = ifr.ifr_ifindex;
  if (::bind(s.get(), reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0)
    throw CanChannelError(uri + ": cannot bind to '" + iface + "': " + errno_text());
  return std::make_unique<RecordSocketChannel>(uri, iface, std::move(s), options.write_timeout_ms);
}

sockaddr_un unix_address(const std::string& uri, const std::string& path) {
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  if (path.size() >= sizeof addr.sun_path)
    throw CanChannelError(uri + ": socket path longer than " + std::to_string(sizeof addr.sun_path - 1) +
                          " bytes");
  std::memcpy(addr.sun_path, path.c_str(), path.size());
  return addr;
}

std::unique_ptr<CanChannel> open_unixcan_connect(const std::string& uri, const std::string& path,
                                                 const CanOpenOptions& options) {
  Fd s(::socket(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC, 0));
  if (s.get() < 0) throw CanChannelError(uri + ": cannot create a unix socket: " + errno_text());
  configure_socket(s.get(), options, uri);  // before connect: the first frames carry timestamps too
  const sockaddr_un addr = unix_address(uri, path);
  if (::connect(s.get(), reinterpret_cast<const sockaddr*>(&addr), sizeof addr) != 0)
    throw CanChannelError(uri + ": cannot connect to " + path + ": " + errno_text() +
                          " (is the simulator or bus listening there?)");
  return std::make_unique<RecordSocketChannel>(uri, options.log_interface, std::move(s), options.write_timeout_ms);
}

// ------------------------------------------------------------------------------ unixcan listener

/// The bus side of unixcan: accepts peers; what one peer writes is delivered to read() and to the
/// other peers; what write() sends goes to every peer. fd() is an epoll descriptor covering the
/// listening socket and all peers, so one poll on it wakes for a new peer or a new frame.
class UnixCanListener final : public CanChannel {
 public:
  UnixCanListener(const std::string& uri, const std::string& path, const CanOpenOptions& options)
      : CanChannel(uri, options.log_interface), path_(path), options_(options) {
    const sockaddr_un addr = unix_address(uri, path);
    struct stat st {};
    if (::lstat(path.c_str(), &st) == 0) {
      if (!S_ISSOCK(st.st_mode))
        throw CanChannelError(uri + ": " + path + " exists and is not a socket; refusing to replace it");
      Fd probe(::socket(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC, 0));
      if (probe.get() >= 0 && ::connect(probe.get(), reinterpret_cast<const sockaddr*>(&addr), sizeof addr) == 0)
        throw CanChannelError(uri + ": another process is already listening on " + path);
      ::unlink(path.c_str());  // stale socket of a process that died
    }
    listen_ = Fd(::socket(AF_UNIX, SOCK_SEQPACKET | SOCK_NONBLOCK | SOCK_CLOEXEC, 0));
    if (listen_.get() < 0) throw CanChannelError(uri + ": cannot create a unix socket: " + errno_text());
    if (::bind(listen_.get(), reinterpret_cast<const sockaddr*>(&addr), sizeof addr) != 0)
      throw CanChannelError(uri + ": cannot bind " + path + ": " + errno_text());
    bound_ = true;
    if (::listen(listen_.get(), 16) != 0) throw CanChannelError(uri + ": cannot listen: " + errno_text());
    epoll_ = Fd(::epoll_create1(EPOLL_CLOEXEC));
    if (epoll_.get() < 0) throw CanChannelError(uri + ": epoll_create1 failed: " + errno_text());
    add_to_epoll(listen_.get());
  }
  ~UnixCanListener() override {
    if (bound_) ::unlink(path_.c_str());
  }

  int fd() const override { return epoll_.get(); }
  bool at_end() const override { return false; }

  std::size_t read(std::vector<ReceivedFrame>& out, std::size_t max_frames) override {
    accept_peers();
    std::size_t got = 0;
    for (std::size_t i = 0; i < peers_.size() && got < max_frames;) {
      bool eof = false;
      const std::size_t first = out.size();
      const std::size_t n = read_records(peers_[i].get(), out, max_frames - got, counters_, eof, uri());
      got += n;
      if (n > 0 && peers_.size() > 1) forward(i, out, first);
      if (eof) {
        drop_peer(i);
        continue;
      }
      ++i;
    }
    return got;
  }

  std::size_t write(const CanFrame* frames, std::size_t count) override {
    accept_peers();
    for (std::size_t i = 0; i < peers_.size();) {
      bool dead = false;
      const std::size_t sent = write_records(peers_[i].get(), frames, count, dead, uri(), options_.write_timeout_ms);
      counters_.tx_overflow += count - sent;
      if (dead) {
        drop_peer(i);
        continue;
      }
      ++i;
    }
    counters_.tx_frames += count;  // on the bus; a slow peer's refusal is its tx_overflow
    return count;
  }

 private:
  void add_to_epoll(int fd) {
    epoll_event ev{};
    ev.events = EPOLLIN;
    ev.data.fd = fd;
    if (::epoll_ctl(epoll_.get(), EPOLL_CTL_ADD, fd, &ev) != 0)
      throw CanChannelError(uri() + ": epoll_ctl failed: " + errno_text());
  }
  void accept_peers() {
    for (;;) {
      Fd p(::accept4(listen_.get(), nullptr, nullptr, SOCK_NONBLOCK | SOCK_CLOEXEC));
      if (p.get() < 0) {
        if (errno == EINTR || errno == ECONNABORTED) continue;
        if (errno == EAGAIN || errno == EWOULDBLOCK) return;
        throw CanChannelError(uri() + ": accept failed: " + errno_text());
      }
      configure_socket(p.get(), options_, uri());
      add_to_epoll(p.get());
      peers_.push_back(std::move(p));
      ++counters_.peers_connected;
    }
  }
  void drop_peer(std::size_t i) {
    ::epoll_ctl(epoll_.get(), EPOLL_CTL_DEL, peers_[i].get(), nullptr);
    peers_.erase(peers_.begin() + static_cast<std::ptrdiff_t>(i));
  }
  void forward(std::size_t from, const std::vector<ReceivedFrame>& frames, std::size_t first) {
    std::vector<CanFrame> f;
    f.reserve(frames.size() - first);
    for (std::size_t k = first; k < frames.size(); ++k) f.push_back(frames[k].frame);
    for (std::size_t j = 0; j < peers_.size(); ++j) {
      if (j == from) continue;
      bool dead = false;
      counters_.tx_overflow += f.size() - write_records(peers_[j].get(), f.data(), f.size(), dead, uri(), 0);
    }
  }

  std::string path_;
  CanOpenOptions options_;
  Fd listen_, epoll_;
  std::vector<Fd> peers_;
  bool bound_ = false;
};

// --------------------------------------------------------------------------------------- candump

class CandumpChannel final : public CanChannel {
 public:
  CandumpChannel(const std::string& uri, const std::string& path, const CanOpenOptions& options)
      : CanChannel(uri, options.log_interface), reader_(path), speed_(options.replay_speed) {
    if (!(speed_ >= 0.0) || !std::isfinite(speed_))
      throw CanChannelError(uri + ": replay_speed must be >= 0 (0 = as fast as read)");
    if (speed_ > 0.0) {
      timer_ = Fd(::timerfd_create(CLOCK_MONOTONIC, TFD_NONBLOCK | TFD_CLOEXEC));
      if (timer_.get() < 0) throw CanChannelError(uri + ": timerfd_create failed: " + errno_text());
      start_mono_ns_ = monotonic_now_ns();
      arm_for_next();
    }
  }
  int fd() const override { return speed_ > 0.0 ? timer_.get() : reader_.fd(); }
  bool at_end() const override { return end_ && !pending_; }
  std::size_t write(const CanFrame*, std::size_t) override {
    throw CanChannelError(uri() + ": a candump replay is read-only");
  }

  std::size_t read(std::vector<ReceivedFrame>& out, std::size_t max_frames) override {
    std::size_t got = 0;
    if (speed_ > 0.0) {
      uint64_t expirations = 0;
      while (::read(timer_.get(), &expirations, sizeof expirations) < 0 && errno == EINTR) {
      }
    }
    const int64_t now = speed_ > 0.0 ? monotonic_now_ns() : 0;
    while (got < max_frames) {
      if (!fetch()) break;
      if (speed_ > 0.0 && due_ns(*pending_) > now) break;
      deliver(*pending_, out);
      pending_.reset();
      ++got;
    }
    if (speed_ > 0.0) arm_for_next();
    counters_.rx_malformed = reader_.truncated_lines();
    return got;
  }

 private:
  bool fetch() {
    if (pending_) return true;
    if (end_) return false;
    CandumpRecord r;
    if (!reader_.next(r)) {
      end_ = true;
      return false;
    }
    if (!have_t0_) {
      t0_ns_ = r.frame.rx_time_ns;
      have_t0_ = true;
    }
    pending_ = r.frame;
    return true;
  }
  int64_t due_ns(const ReceivedFrame& f) const {
    return start_mono_ns_ + static_cast<int64_t>(static_cast<double>(f.rx_time_ns - t0_ns_) / speed_);
  }
  void deliver(const ReceivedFrame& f, std::vector<ReceivedFrame>& out) {
    if (f.frame.is_error()) ++counters_.rx_error_frames;
    ++counters_.rx_frames;
    out.push_back(f);
  }
  void arm_for_next() {
    // Absolute expiry at the next frame's due time; at the end, fire at once so a poller wakes and
    // sees at_end().
    itimerspec its{};
    int64_t due = fetch() ? due_ns(*pending_) : 0;
    if (due <= monotonic_now_ns()) due = monotonic_now_ns() + 1;
    its.it_value.tv_sec = static_cast<time_t>(due / 1000000000);
    its.it_value.tv_nsec = static_cast<long>(due % 1000000000);
    if (::timerfd_settime(timer_.get(), TFD_TIMER_ABSTIME, &its, nullptr) != 0)
      throw CanChannelError(uri() + ": timerfd_settime failed: " + errno_text());
  }

  CandumpReader reader_;
  double speed_;
  Fd timer_;
  int64_t start_mono_ns_ = 0;
  int64_t t0_ns_ = 0;
  bool have_t0_ = false;
  bool end_ = false;
  std::optional<ReceivedFrame> pending_;
};

}  // namespace

bool CanChannel::wait_readable(int timeout_ms) const { return poll_fd(fd(), POLLIN, timeout_ms); }

std::unique_ptr<CanChannel> CanChannel::open(const std::string& uri, const CanOpenOptions& options) {
  const std::size_t colon = uri.find(':');
  const std::string scheme = colon == std::string::npos ? std::string() : uri.substr(0, colon);
  const std::string rest = colon == std::string::npos ? std::string() : uri.substr(colon + 1);
  if (scheme.empty() || rest.empty())
    throw CanChannelError("CAN channel '" + uri +
                          "': expected socketcan:IFACE, unixcan:PATH or candump:FILE");
  if (scheme == "socketcan") return open_socketcan(uri, rest, options);
  if (scheme == "unixcan") {
    if (options.listen) return std::make_unique<UnixCanListener>(uri, rest, options);
    return open_unixcan_connect(uri, rest, options);
  }
  if (scheme == "candump") {
    try {
      return std::make_unique<CandumpChannel>(uri, rest, options);
    } catch (const CandumpParseError& e) {
      throw CanChannelError(uri + ": " + e.what());
    }
  }
  throw CanChannelError("CAN channel '" + uri + "': unknown transport '" + scheme +
                        "' (expected socketcan, unixcan or candump)");
}

std::pair<std::unique_ptr<CanChannel>, std::unique_ptr<CanChannel>> CanChannel::unix_pair(
    const CanOpenOptions& options) {
  int sv[2];
  if (::socketpair(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC, 0, sv) != 0)
    throw CanChannelError(std::string("unixcan socketpair: ") + errno_text());
  Fd a(sv[0]), b(sv[1]);
  configure_socket(a.get(), options, "unixcan:<pair>");
  configure_socket(b.get(), options, "unixcan:<pair>");
  return {std::make_unique<RecordSocketChannel>("unixcan:<pair>/0", options.log_interface, std::move(a),
                                                options.write_timeout_ms),
          std::make_unique<RecordSocketChannel>("unixcan:<pair>/1", options.log_interface, std::move(b),
                                                options.write_timeout_ms)};
}

}  // namespace imucal::drivers::imu
