// The throw-away PostgreSQL cluster of the fleet tests (tests/support/pg_cluster.hpp): a test
// process killed with SIGKILL — what ctest does to a test past its timeout — leaves no server
// running and no cluster directory behind (its watchdog stops and removes them); a test that ends
// normally stops its own.
#include "tests/support/pg_cluster.hpp"

#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <chrono>
#include <filesystem>
#include <sstream>
#include <string>
#include <thread>

namespace {

using imucal::test_support::PgCluster;

bool accepts_connections(int port) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(static_cast<uint16_t>(port));
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  const bool ok = ::connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0;
  ::close(fd);
  return ok;
}

/// Polls `gone` for up to 30 s.
template <typename F>
bool within_30s(F gone) {
  for (int i = 0; i < 300; ++i) {
    if (gone()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  return false;
}

TEST(PgCluster, ATestKilledWithSigkillLeavesNoServerAndNoDirectoryBehind) {
  int fds[2];
  ASSERT_EQ(::pipe(fds), 0);
  const pid_t test = ::fork();
  ASSERT_GE(test, 0);
  if (test == 0) {  // the "test": a cluster, its port and directory reported, then it waits
    ::close(fds[0]);
    std::string line = "error\n";
    try {
      static PgCluster pg;  // never destroyed: the process is killed
      line = std::to_string(pg.port()) + " " + pg.directory() + "\n";
    } catch (const std::exception& e) {
      line = std::string("error ") + e.what() + "\n";
    }
    if (::write(fds[1], line.data(), line.size()) < 0) ::_exit(1);
    for (;;) ::pause();
  }
  ::close(fds[1]);
  std::string line;
  char c = 0;
  while (::read(fds[0], &c, 1) == 1 && c != '\n') line += c;
  ::close(fds[0]);
  std::istringstream in(line);
  int port = 0;
  std::string dir;
  in >> port >> dir;
  ASSERT_GT(port, 0) << line;
  ASSERT_TRUE(accepts_connections(port)) << "the cluster was not up";
  ASSERT_TRUE(std::filesystem::exists(dir));

  ::kill(test, SIGKILL);
  ::waitpid(test, nullptr, 0);
  EXPECT_TRUE(within_30s([&] { return !accepts_connections(port); }))
      << "the server on port " << port << " outlived its test";
  EXPECT_TRUE(within_30s([&] { return !std::filesystem::exists(dir); }))
      << dir << " outlived its test";
}

TEST(PgCluster, ATestThatEndsNormallyStopsItsServer) {
  int port = 0;
  std::string dir;
  {
    PgCluster pg;
    port = pg.port();
    dir = pg.directory();
    ASSERT_TRUE(accepts_connections(port));
  }
  EXPECT_FALSE(accepts_connections(port));
  EXPECT_FALSE(std::filesystem::exists(dir));
}

}  // namespace
