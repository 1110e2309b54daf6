#pragma once
// A throw-away PostgreSQL cluster for one test (issue #24 item 5): initdb in a temporary directory,
// its own free port on 127.0.0.1, its own socket directory, run as an unprivileged user (the
// `postgres` account of Debian's postgresql package when the test runs as root — initdb refuses
// root — or the test's own user otherwise). Password (SCRAM) authentication over TCP, so the
// credentials paths of the fleet store are real:
//   fleet_writer  owns the database `fleet` (the stations' senders: create the schema, write)
//   fleet_reader  pg_read_all_data only (stationctl --fleet, stationweb): no write grant at all
// kill9() and start() let a test kill the server the hard way and bring it back.
// A test process that dies without its destructor (ctest's timeout kills it with SIGKILL) leaves no
// server behind: a watchdog process of its own session waits on a pipe from the test and, when the
// pipe closes unannounced, stops the server and removes its directory.
#include <errno.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <pwd.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <thread>

#include "tests/support/run_command.hpp"
#include "tests/support/temp_dir.hpp"

namespace imucal::test_support {

inline int free_tcp_port() {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t len = sizeof a;
  if (fd < 0 || ::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0 ||
      ::getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len) != 0)
    throw std::runtime_error("no free TCP port");
  const int port = ntohs(a.sin_port);
  ::close(fd);
  return port;
}

class PgCluster {
 public:
  static constexpr const char* kWriterPassword = "w-Secr3t;'\"pw";
  static constexpr const char* kReaderPassword = "r-Secr3t";

  PgCluster() : dir_("imucal_pg") {
    bin_ = find_bindir();
    port_ = free_tcp_port();
    std::filesystem::permissions(dir_.path(), std::filesystem::perms::owner_all |
                                                  std::filesystem::perms::group_exec |
                                                  std::filesystem::perms::others_exec);
    as_user_ = ::geteuid() == 0 ? "runuser -u postgres -- " : "";
    std::filesystem::create_directories(data_dir());
    std::filesystem::create_directories(socket_dir());
    if (::geteuid() == 0) {
      const passwd* pw = ::getpwnam("postgres");
      if (!pw) throw std::runtime_error("no `postgres` user (install Debian's postgresql package)");
      for (const std::string& d : {data_dir(), socket_dir()})
        if (::chown(d.c_str(), pw->pw_uid, pw->pw_gid) != 0)
          throw std::runtime_error("chown " + d + " failed");
    }
    start_watchdog();
    must(as_user_ + bin_ + "/initdb -D " + data_dir() +
             " -U imucal_admin -A trust -E UTF8 --no-sync -N >/dev/null 2>&1",
         "initdb");
    std::ofstream(data_dir() + "/pg_hba.conf")
        << "local all all trust\nhost all imucal_admin 127.0.0.1/32 trust\n"
           "host all all 127.0.0.1/32 scram-sha-256\n";
    start();
    admin("CREATE ROLE fleet_writer LOGIN PASSWORD " + quoted(kWriterPassword));
    admin("CREATE ROLE fleet_reader LOGIN PASSWORD " + quoted(kReaderPassword));
    admin("CREATE DATABASE fleet OWNER fleet_writer");
    admin("GRANT pg_read_all_data TO fleet_reader");
  }
  ~PgCluster() {
    run_command(as_user_ + bin_ + "/pg_ctl -D " + data_dir() +
                " -m immediate stop >/dev/null 2>&1");
    stop_watchdog();
  }
  PgCluster(const PgCluster&) = delete;
  PgCluster& operator=(const PgCluster&) = delete;

  int port() const { return port_; }
  /// The cluster's directory (data, socket, log): removed with it.
  const std::string& directory() const { return dir_.path(); }
  /// postgresql://ROLE@127.0.0.1:PORT/fleet (the password comes separately).
  std::string url(const std::string& role) const {
    return "postgresql://" + role + "@127.0.0.1:" + std::to_string(port_) + "/fleet";
  }
  std::string log_file() const { return socket_dir() + "/server.log"; }

  /// SQL as the cluster's superuser over the socket; throws with psql's words on failure.
  std::string admin(const std::string& sql, const std::string& db = "postgres") const {
    const std::string file = dir_.sub("admin.sql");
    std::ofstream(file) << sql << ";\n";
    ::chmod(file.c_str(), 0644);
    const CommandResult r = run_command(
        as_user_ + bin_ + "/psql -X -q -t -A -v ON_ERROR_STOP=1 -h " + socket_dir() + " -p " +
        std::to_string(port_) + " -U imucal_admin -d " + db + " -f " + file + " 2>&1");
    if (r.code != 0) throw std::runtime_error("psql: " + sql + ": " + r.out);
    return r.out;
  }

  void start() {
    // After a SIGKILL the old backends may still hold the shared memory for a moment: retry.
    std::string why;
    for (int attempt = 0; attempt < 40; ++attempt) {
      const CommandResult r = run_command(
          as_user_ + bin_ + "/pg_ctl -D " + data_dir() + " -w -t 30 -l " + log_file() +
          " -o \"-p " + std::to_string(port_) + " -k " + socket_dir() +
          " -c listen_addresses=127.0.0.1 -c fsync=off -c max_connections=200\" start 2>&1");
      if (r.code == 0) return;
      why = r.out;
      std::this_thread::sleep_for(std::chrono::milliseconds(250));
    }
    throw std::runtime_error("the PostgreSQL test cluster did not start: " + why);
  }

  /// SIGKILL to the postmaster (no shutdown, no checkpoint), then waits until it is gone.
  void kill9() {
    std::ifstream pid_file(data_dir() + "/postmaster.pid");
    pid_t pid = 0;
    pid_file >> pid;
    if (pid <= 0) throw std::runtime_error("no postmaster.pid");
    ::kill(pid, SIGKILL);
    for (int i = 0; i < 200 && ::kill(pid, 0) == 0; ++i)
      std::this_thread::sleep_for(std::chrono::milliseconds(25));
  }

 private:
  static std::string find_bindir() {
    for (int v = 19; v >= 13; --v) {
      const std::string d = "/usr/lib/postgresql/" + std::to_string(v) + "/bin";
      if (std::filesystem::exists(d + "/initdb")) return d;
    }
    throw std::runtime_error(
        "no PostgreSQL server binaries under /usr/lib/postgresql/*/bin (tools/setup.sh installs "
        "Debian's postgresql)");
  }
  static std::string quoted(const std::string& s) {
    std::string out = "'";
    for (char ch : s) out += ch == '\'' ? std::string("''") : std::string(1, ch);
    return out + "'";
  }
  static void must(const std::string& cmd, const char* what) {
    const CommandResult r = run_command(cmd);
    if (r.code != 0) throw std::runtime_error(std::string(what) + " failed: " + r.out);
  }
  /// Forks the watchdog: its own session (a kill of the test's process group spares it), every
  /// descriptor but the pipe's read end closed; one byte from the pipe: the test ended normally,
  /// exit; end of file: the test died, stop the server and remove the directory.
  void start_watchdog() {
    int fds[2];
    if (::pipe2(fds, O_CLOEXEC) != 0) throw std::runtime_error("pipe failed");
    const std::string cleanup = as_user_ + bin_ + "/pg_ctl -D " + data_dir() +
                                " -m immediate stop >/dev/null 2>&1; rm -rf '" + dir_.path() + "'";
    const pid_t pid = ::fork();
    if (pid < 0) throw std::runtime_error("fork failed");
    if (pid == 0) {  // only async-signal-safe calls from here
      ::setsid();
      for (int fd = 3; fd < 1024; ++fd)
        if (fd != fds[0]) ::close(fd);
      char byte = 0;
      ssize_t n = 0;
      do n = ::read(fds[0], &byte, 1);
      while (n < 0 && errno == EINTR);
      if (n == 1) ::_exit(0);
      ::execl("/bin/sh", "sh", "-c", cleanup.c_str(), static_cast<char*>(nullptr));
      ::_exit(127);
    }
    ::close(fds[0]);
    watchdog_fd_ = fds[1];
    watchdog_pid_ = pid;
  }
  void stop_watchdog() {
    if (watchdog_pid_ <= 0) return;
    // A watchdog already gone (killed) must not turn the write into a SIGPIPE.
    if (::waitpid(watchdog_pid_, nullptr, WNOHANG) == 0) {
      const char byte = 'q';
      if (::write(watchdog_fd_, &byte, 1) != 1) {
        // Nothing to do: without the byte the watchdog cleans up what is already stopped.
      }
      ::waitpid(watchdog_pid_, nullptr, 0);
    }
    ::close(watchdog_fd_);
    watchdog_pid_ = -1;
  }

  std::string data_dir() const { return dir_.sub("data"); }
  std::string socket_dir() const { return dir_.sub("sock"); }

  ScopedTempDir dir_;
  std::string bin_;
  std::string as_user_;
  int port_ = 0;
  int watchdog_fd_ = -1;
  pid_t watchdog_pid_ = -1;
};

}  // namespace imucal::test_support
