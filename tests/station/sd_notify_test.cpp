// Own sd_notify: a datagram socket standing in for systemd's notify socket receives exactly what the
// daemon sends (READY=1, STATUS=, WATCHDOG=1, STOPPING=1), over a path socket and an abstract one;
// the watchdog interval is half of $WATCHDOG_USEC and only ours when $WATCHDOG_PID matches.
#include "station/daemon/sd_notify.hpp"

#include <gtest/gtest.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <cstddef>
#include <cstdlib>
#include <cstring>
#include <string>

namespace imucal::station {
using namespace imucal::station::daemon;
namespace {

/// A bound AF_UNIX datagram socket (what systemd listens on).
class FakeSystemdSdNotify {
 public:
  explicit FakeSystemdSdNotify(const std::string& name) : name_(name) {
    fd_ = ::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    EXPECT_GE(fd_, 0);
    sockaddr_un a{};
    a.sun_family = AF_UNIX;
    std::memcpy(a.sun_path, name.data(), name.size());
    if (name[0] == '@') {
      a.sun_path[0] = '\0';
    } else {
      ::unlink(name.c_str());
    }
    const socklen_t len = static_cast<socklen_t>(offsetof(sockaddr_un, sun_path) + name.size());
    EXPECT_EQ(::bind(fd_, reinterpret_cast<sockaddr*>(&a), len), 0) << std::strerror(errno);
  }
  ~FakeSystemdSdNotify() {
    ::close(fd_);
    if (name_[0] != '@') ::unlink(name_.c_str());
  }
  /// Next datagram, or "" after 2 s.
  std::string receive() {
    pollfd p{fd_, POLLIN, 0};
    if (::poll(&p, 1, 2000) != 1) return "";
    char buf[4096];
    const ssize_t n = ::recv(fd_, buf, sizeof buf, 0);
    return n > 0 ? std::string(buf, static_cast<size_t>(n)) : "";
  }

 private:
  std::string name_;
  int fd_ = -1;
};

TEST(SdNotify, PathSocketReceivesReadyStatusWatchdogStopping) {
  const std::string path = "/tmp/imucal-sdnotify-" + std::to_string(getpid()) + ".sock";
  FakeSystemdSdNotify systemd(path);
  const SdNotifier n(path, std::nullopt);
  ASSERT_TRUE(n.enabled());
  EXPECT_TRUE(n.ready("idle"));
  EXPECT_EQ(systemd.receive(), "READY=1\nSTATUS=idle");
  EXPECT_TRUE(n.status("run 3: step 2/27"));
  EXPECT_EQ(systemd.receive(), "STATUS=run 3: step 2/27");
  EXPECT_TRUE(n.watchdog());
  EXPECT_EQ(systemd.receive(), "WATCHDOG=1");
  EXPECT_TRUE(n.stopping());
  EXPECT_EQ(systemd.receive(), "STOPPING=1");
}

TEST(SdNotify, AbstractSocketFromTheEnvironment) {
  const std::string name = "@imucal-sdnotify-test-" + std::to_string(getpid());
  FakeSystemdSdNotify systemd(name);
  ::setenv("NOTIFY_SOCKET", name.c_str(), 1);
  ::setenv("WATCHDOG_USEC", "3000000", 1);
  ::unsetenv("WATCHDOG_PID");
  const SdNotifier n = SdNotifier::from_environment();
  EXPECT_EQ(n.socket(), name);
  ASSERT_TRUE(n.watchdog_interval().has_value());
  EXPECT_EQ(n.watchdog_interval()->count(), 1500000);  // half of WATCHDOG_USEC
  EXPECT_TRUE(n.ready());
  EXPECT_EQ(systemd.receive(), "READY=1");
  EXPECT_TRUE(n.watchdog());
  EXPECT_EQ(systemd.receive(), "WATCHDOG=1");
  ::unsetenv("NOTIFY_SOCKET");
  ::unsetenv("WATCHDOG_USEC");
}

TEST(SdNotify, WatchdogBelongsToThePidSystemdNamed) {
  ::setenv("NOTIFY_SOCKET", "@x", 1);
  ::setenv("WATCHDOG_USEC", "1000000", 1);
  ::setenv("WATCHDOG_PID", std::to_string(getpid() + 1).c_str(), 1);
  EXPECT_FALSE(SdNotifier::from_environment().watchdog_interval().has_value());
  ::setenv("WATCHDOG_PID", std::to_string(getpid()).c_str(), 1);
  EXPECT_TRUE(SdNotifier::from_environment().watchdog_interval().has_value());
  ::setenv("WATCHDOG_USEC", "12abc", 1);
  EXPECT_FALSE(SdNotifier::from_environment().watchdog_interval().has_value());
  ::unsetenv("NOTIFY_SOCKET");
  ::unsetenv("WATCHDOG_USEC");
  ::unsetenv("WATCHDOG_PID");
}

TEST(SdNotify, WithoutSystemdEverythingIsANoOpThatSaysSo) {
  ::unsetenv("NOTIFY_SOCKET");
  const SdNotifier n = SdNotifier::from_environment();
  EXPECT_FALSE(n.enabled());
  std::string why;
  EXPECT_FALSE(n.notify("READY=1", &why));
  EXPECT_NE(why.find("NOTIFY_SOCKET"), std::string::npos);
  // A socket nobody listens on: the send fails and says where.
  const SdNotifier dead("/tmp/imucal-no-such-notify-socket", std::nullopt);
  EXPECT_FALSE(dead.notify("READY=1", &why));
  EXPECT_NE(why.find("/tmp/imucal-no-such-notify-socket"), std::string::npos);
}

}  // namespace
}  // namespace imucal::station
