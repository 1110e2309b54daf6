#pragma once
// A TCP forwarder on 127.0.0.1 for network-cut tests (issue #24): a client connects to port(), its
// bytes go to the target port and back. cut() drops every live connection (RST) and closes the
// listening socket, so new connections are refused — as a firewall REJECT rule on the port would —
// until restore(). One thread accepts; each connection is pumped by one thread with poll().
#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <mutex>
#include <set>
#include <stdexcept>
#include <thread>
#include <vector>

namespace imucal::test_support {

class TcpProxy {
 public:
  explicit TcpProxy(int target_port) : target_port_(target_port) {
    open_listener(0);
    acceptor_ = std::thread([this] { accept_loop(); });
  }
  ~TcpProxy() {
    stop_ = true;
    cut();
    if (acceptor_.joinable()) acceptor_.join();
    for (auto& t : pumps_) t.join();
  }
  TcpProxy(const TcpProxy&) = delete;
  TcpProxy& operator=(const TcpProxy&) = delete;

  int port() const { return port_; }

  void cut() {
    std::lock_guard<std::mutex> lk(mu_);
    cut_ = true;
    if (listen_fd_ >= 0) {
      ::shutdown(listen_fd_, SHUT_RDWR);
      ::close(listen_fd_);
      listen_fd_ = -1;
    }
    for (int fd : live_) {
      linger l{1, 0};  // close with RST: the peer sees the connection reset, not a clean end
      ::setsockopt(fd, SOL_SOCKET, SO_LINGER, &l, sizeof l);
      ::shutdown(fd, SHUT_RDWR);
    }
  }

  void restore() {
    std::lock_guard<std::mutex> lk(mu_);
    open_listener_locked(port_);
    cut_ = false;
  }

 private:
  void open_listener(int port) {
    std::lock_guard<std::mutex> lk(mu_);
    open_listener_locked(port);
  }
  void open_listener_locked(int port) {
    const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
    const int on = 1;
    ::setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &on, sizeof on);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    a.sin_port = htons(static_cast<uint16_t>(port));
    socklen_t len = sizeof a;
    if (::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0 || ::listen(fd, 64) != 0 ||
        ::getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len) != 0) {
      ::close(fd);
      throw std::runtime_error("TcpProxy: cannot listen on port " + std::to_string(port));
    }
    port_ = ntohs(a.sin_port);
    listen_fd_ = fd;
  }

  void accept_loop() {
    while (!stop_) {
      int lfd;
      {
        std::lock_guard<std::mutex> lk(mu_);
        lfd = listen_fd_;
      }
      if (lfd < 0) {
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
        continue;
      }
      pollfd p{lfd, POLLIN, 0};
      if (::poll(&p, 1, 50) <= 0) continue;
      const int client = ::accept(lfd, nullptr, nullptr);
      if (client < 0) continue;
      const int server = connect_target();
      std::lock_guard<std::mutex> lk(mu_);
      if (server < 0 || cut_) {
        ::close(client);
        if (server >= 0) ::close(server);
        continue;
      }
      live_.insert(client);
      live_.insert(server);
      pumps_.emplace_back([this, client, server] { pump(client, server); });
    }
  }

  int connect_target() const {
    const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    a.sin_port = htons(static_cast<uint16_t>(target_port_));
    if (::connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0) {
      ::close(fd);
      return -1;
    }
    return fd;
  }

  void pump(int a, int b) {
    char buf[16384];
    pollfd p[2] = {{a, POLLIN, 0}, {b, POLLIN, 0}};
    for (;;) {
      if (::poll(p, 2, 100) < 0) break;
      bool done = false;
      for (int i = 0; i < 2 && !done; ++i) {
        if (!(p[i].revents & (POLLIN | POLLHUP | POLLERR))) continue;
        const ssize_t n = ::read(p[i].fd, buf, sizeof buf);
        if (n <= 0 || !write_all(p[1 - i].fd, buf, static_cast<std::size_t>(n))) done = true;
      }
      if (done || stop_) break;
    }
    std::lock_guard<std::mutex> lk(mu_);
    live_.erase(a);
    live_.erase(b);
    ::close(a);
    ::close(b);
  }

  /// MSG_NOSIGNAL: a peer gone (the server killed, a client closed) is a failed send, not a SIGPIPE
  /// that ends the test process (seen once idle senders began probing through the proxy).
  static bool write_all(int fd, const char* p, std::size_t n) {
    while (n > 0) {
      const ssize_t w = ::send(fd, p, n, MSG_NOSIGNAL);
      if (w <= 0) return false;
      p += w;
      n -= static_cast<std::size_t>(w);
    }
    return true;
  }

  int target_port_;
  int port_ = 0;
  int listen_fd_ = -1;
  std::atomic<bool> stop_{false};
  bool cut_ = false;
  std::mutex mu_;
  std::set<int> live_;
  std::vector<std::thread> pumps_;
  std::thread acceptor_;
};

}  // namespace imucal::test_support
