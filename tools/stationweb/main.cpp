// stationweb: QA's read-only web view of a calibration history (issue #24 item 4). It opens a
// station's SQLite history read-only and serves HTML pages (tools/stationweb/pages.hpp) over HTTP
// on the loopback interface unless told otherwise:
//
//   stationweb --db /var/lib/imucal/history.db [--listen 127.0.0.1:8090] [--log-level info]
//
// Once listening it prints one line on stdout, "stationweb: serving <source> on
// http://HOST:PORT/" (with --listen HOST:0 the port the system chose), and serves until SIGINT or
// SIGTERM. Exit codes: 0 stopped by a signal, 1 the history cannot be opened or the address not
// bound, 2 usage.
#include <signal.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <cerrno>
#include <cstring>
#include <iostream>
#include <string>
#include <thread>

#include "db/fleet/fleet_url.hpp"
#include "station/daemon/logging.hpp"
#include "tools/stationweb/history_source.hpp"
#include "tools/stationweb/server.hpp"

namespace {

using namespace imucal;

struct Listen {
  std::string host;
  int port = 0;
};

/// "HOST:PORT" (IPv6 as "[::1]:8090"); std::invalid_argument naming the option otherwise.
Listen parse_listen(const std::string& text) {
  const std::size_t colon = text.rfind(':');
  if (colon == std::string::npos || colon == 0 || colon + 1 == text.size())
    throw std::invalid_argument("--listen \"" + text +
                                "\": expected HOST:PORT, e.g. 127.0.0.1:8090");
  Listen l;
  l.host = text.substr(0, colon);
  if (l.host.size() > 2 && l.host.front() == '[' && l.host.back() == ']')
    l.host = l.host.substr(1, l.host.size() - 2);
  const std::string port = text.substr(colon + 1);
  if (port.size() > 5 || port.find_first_not_of("0123456789") != std::string::npos ||
      std::stoi(port) > 65535)
    throw std::invalid_argument("--listen \"" + text + "\": port must be 0..65535 (0: any free)");
  l.port = std::stoi(port);
  return l;
}

bool is_loopback(const std::string& host) {
  return host == "localhost" || host == "::1" || host.rfind("127.", 0) == 0;
}

/// Stops the server on SIGINT/SIGTERM: the signals are blocked in every thread and taken by
/// sigwait in this one, so nothing runs in a signal handler.
std::thread stop_on_signal(httplib::Server& server, const sigset_t& signals) {
  return std::thread([&server, signals] {
    int sig = 0;
    sigwait(&signals, &sig);
    spdlog::info("signal {}: stopping", sig);
    server.stop();
  });
}

int serve(const std::string& source, const std::string& password, const Listen& listen) {
  tools::stationweb::History history = tools::stationweb::open_history(source, password);
  httplib::Server server;
  tools::stationweb::install_routes(server, history);
  const int port = listen.port == 0
                       ? server.bind_to_any_port(listen.host)
                       : (server.bind_to_port(listen.host, listen.port) ? listen.port : -1);
  if (port < 0) {
    std::cerr << "stationweb: cannot listen on " << listen.host << ":" << listen.port << ": "
              << std::strerror(errno) << "\n";
    return 1;
  }
  if (!is_loopback(listen.host))
    spdlog::warn("listening on {}, not loopback: whoever reaches it can read the history",
                 listen.host);
  std::cout << "stationweb: serving " << history.label << " on http://"
            << (listen.host.find(':') != std::string::npos ? "[" + listen.host + "]" : listen.host)
            << ":" << port << "/" << std::endl;
  spdlog::info("serving {} on {}:{}", history.label, listen.host, port);
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  std::thread stopper = stop_on_signal(server, signals);
  server.listen_after_bind();
  stopper.join();
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"stationweb: read-only QA web view of a calibration history"};
  std::string db, password_file, listen_text = "127.0.0.1:8090", level = "info";
  app.add_option("--db", db,
                 "the station's SQLite history (opened read-only), or the fleet store's "
                 "postgresql://USER@HOST:PORT/DB (log in as a read-only role)")
      ->required();
  app.add_option("--password-file", password_file,
                 "the fleet store password's file (first line); default PGPASSWORD or ~/.pgpass");
  app.add_option("--listen", listen_text,
                 "HOST:PORT to serve on (loopback by default; port 0: any)")
      ->capture_default_str();
  app.add_option("--log-level", level, "trace, debug, info, warn, error")->capture_default_str();
  app.set_version_flag("--version", std::string("stationweb ") + IMUCAL_VERSION);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;  // --help and --version: 0; a usage error: 2
  }
  // Block the stop signals before any thread starts (httplib's pool inherits the mask).
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);
  signal(SIGPIPE, SIG_IGN);  // a client that hangs up must not end the server
  Listen listen;
  try {
    listen = parse_listen(listen_text);
    station::daemon::setup_logging(level, "stationweb");
  } catch (const std::invalid_argument& e) {
    std::cerr << "stationweb: " << e.what() << "\n";
    return 2;
  }
  std::string password;
  try {
    if (!password_file.empty()) password = db::fleet::read_password_file(password_file);
  } catch (const std::exception& e) {
    std::cerr << "stationweb: " << e.what() << "\n";
    return 2;
  }
  try {
    return serve(db, password, listen);
  } catch (const std::exception& e) {
    std::cerr << "stationweb: " << e.what() << "\n";
    return 1;
  }
}
