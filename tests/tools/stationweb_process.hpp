#pragma once
// build/bin/stationweb as a child process on a free loopback port (--listen 127.0.0.1:0): started,
// its "serving ... on http://127.0.0.1:PORT/" line read from its stdout for the port, stopped with
// SIGTERM (and waited for) on destruction. Its stderr goes to a file the caller names. Shared by
// tests/tools/stationweb_test.cpp and the benchmark tests/tools/stationweb_bench.cpp.
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <stdexcept>
#include <string>
#include <vector>

extern char** environ;

namespace imucal::test_support {

class StationwebProcess {
 public:
  StationwebProcess(const std::string& bin, const std::string& db, const std::string& stderr_file,
                    const std::vector<std::string>& extra_args = {}) {
    int out[2];
    if (::pipe(out) != 0) throw std::runtime_error("pipe failed");
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_adddup2(&actions, out[1], STDOUT_FILENO);
    posix_spawn_file_actions_addclose(&actions, out[0]);
    posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, stderr_file.c_str(),
                                     O_WRONLY | O_CREAT | O_TRUNC, 0644);
    std::vector<std::string> args = {bin, "--db", db, "--listen", "127.0.0.1:0"};
    args.insert(args.end(), extra_args.begin(), extra_args.end());
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    const int rc = posix_spawn(&pid_, bin.c_str(), &actions, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&actions);
    ::close(out[1]);
    if (rc != 0) {
      ::close(out[0]);
      throw std::runtime_error("cannot start " + bin);
    }
    first_line_ = read_line(out[0], std::chrono::seconds(20));
    ::close(out[0]);
    const std::size_t colon = first_line_.rfind(':');
    if (first_line_.find("serving") == std::string::npos || colon == std::string::npos)
      throw std::runtime_error("stationweb did not start: \"" + first_line_ + "\" (see " +
                               stderr_file + ")");
    port_ = std::stoi(first_line_.substr(colon + 1));
  }
  ~StationwebProcess() { stop(); }
  StationwebProcess(const StationwebProcess&) = delete;
  StationwebProcess& operator=(const StationwebProcess&) = delete;

  int port() const { return port_; }
  pid_t pid() const { return pid_; }
  const std::string& first_line() const { return first_line_; }
  /// SIGTERM, then the exit status (-1 if it did not exit normally or was stopped before).
  int stop() {
    if (pid_ <= 0) return -1;
    ::kill(pid_, SIGTERM);
    int status = 0;
    ::waitpid(pid_, &status, 0);
    pid_ = -1;
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }

 private:
  static std::string read_line(int fd, std::chrono::seconds timeout) {
    std::string line;
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (std::chrono::steady_clock::now() < deadline) {
      pollfd p{fd, POLLIN, 0};
      if (::poll(&p, 1, 100) <= 0) continue;
      char c = 0;
      if (::read(fd, &c, 1) != 1 || c == '\n') break;
      line += c;
    }
    return line;
  }

  pid_t pid_ = -1;
  int port_ = 0;
  std::string first_line_;
};

}  // namespace imucal::test_support
