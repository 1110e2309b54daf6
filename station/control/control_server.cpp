#include "station/control/control_server.hpp"

#include <errno.h>
#include <fcntl.h>
#include <grp.h>
#include <poll.h>
#include <pwd.h>
#include <spdlog/spdlog.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <list>
#include <stdexcept>
#include <vector>

#include "station/control/record_json.hpp"

namespace imucal::station::control {

using nlohmann::json;

namespace {

constexpr std::size_t kReadChunk = 64 * 1024;

std::string errno_text(int err) { return std::strerror(err); }

sockaddr_un unix_address(const std::string& path) {
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  if (path.empty()) throw std::runtime_error("control socket: empty path");
  if (path.size() >= sizeof addr.sun_path)
    throw std::runtime_error("control socket " + path + ": path longer than " +
                             std::to_string(sizeof addr.sun_path - 1) + " bytes");
  std::memcpy(addr.sun_path, path.c_str(), path.size() + 1);
  return addr;
}

/// A socket file left by a dead daemon is removed; a live one (someone accepts) is an error, and so
/// is anything that is not a socket (never delete a file we did not make).
void replace_stale_socket(const std::string& path) {
  struct stat st {};
  if (::lstat(path.c_str(), &st) != 0) {
    if (errno == ENOENT) return;
    throw std::runtime_error("control socket " + path + ": " + errno_text(errno));
  }
  if (!S_ISSOCK(st.st_mode))
    throw std::runtime_error("control socket " + path +
                             ": exists and is not a socket (refusing to replace it)");
  const int fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) throw std::runtime_error("control socket: socket(): " + errno_text(errno));
  const sockaddr_un addr = unix_address(path);
  const int rc = ::connect(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof addr);
  const int err = errno;
  ::close(fd);
  if (rc == 0)
    throw std::runtime_error("control socket " + path +
                             ": another process is listening there (is stationd already running?)");
  if (err != ECONNREFUSED && err != ENOENT)
    throw std::runtime_error("control socket " + path +
                             ": probing the existing socket: " + errno_text(err));
  if (::unlink(path.c_str()) != 0 && errno != ENOENT)
    throw std::runtime_error("control socket " + path +
                             ": removing the stale socket: " + errno_text(errno));
}

std::string group_name_of(gid_t gid) {
  std::vector<char> buf(16384);
  group gr{};
  group* out = nullptr;
  if (::getgrgid_r(gid, &gr, buf.data(), buf.size(), &out) == 0 && out) return out->gr_name;
  return "gid " + std::to_string(gid);
}

}  // namespace

std::string user_name_of(uid_t uid) {
  std::vector<char> buf(16384);
  passwd pw{};
  passwd* out = nullptr;
  if (::getpwuid_r(uid, &pw, buf.data(), buf.size(), &out) == 0 && out) return out->pw_name;
  return "uid " + std::to_string(uid);
}

bool peer_in_group(uid_t uid, gid_t gid, gid_t group) {
  if (uid == 0 || gid == group) return true;
  std::vector<char> buf(16384);
  passwd pw{};
  passwd* out = nullptr;
  if (::getpwuid_r(uid, &pw, buf.data(), buf.size(), &out) != 0 || !out) return false;
  int n = 64;
  std::vector<gid_t> groups(static_cast<std::size_t>(n));
  while (::getgrouplist(out->pw_name, out->pw_gid, groups.data(), &n) < 0) {
    if (n <= static_cast<int>(groups.size())) return false;  // should not happen: n grew
    groups.resize(static_cast<std::size_t>(n));
  }
  for (int i = 0; i < n; ++i)
    if (groups[static_cast<std::size_t>(i)] == group) return true;
  return false;
}

struct ControlServer::Client {
  int fd = -1;
  ucred cred{};
  std::string user;
  std::string in;
  std::string out;
  std::size_t out_pos = 0;
  bool close_after_write = false;
  bool eof = false;  ///< the peer finished sending
  bool dead = false;
  std::chrono::steady_clock::time_point last_traffic = std::chrono::steady_clock::now();
};

ControlServer::ControlServer(ControlHandler& handler, ControlServerOptions options)
    : handler_(handler), options_(std::move(options)) {}

ControlServer::~ControlServer() { stop(); }

void ControlServer::start() {
  if (running_) throw std::logic_error("ControlServer::start: already running");
  const std::string& path = options_.socket_path;

  // The control group.
  if (options_.group.empty()) {
    group_id_ = ::getgid();
    group_name_ = group_name_of(group_id_);
  } else {
    std::vector<char> buf(16384);
    group gr{};
    group* out = nullptr;
    if (::getgrnam_r(options_.group.c_str(), &gr, buf.data(), buf.size(), &out) != 0 || !out)
      throw std::runtime_error("control socket " + path + ": control group '" + options_.group +
                               "' does not exist");
    group_id_ = out->gr_gid;
    group_name_ = out->gr_name;
  }

  const std::filesystem::path parent = std::filesystem::path(path).parent_path();
  if (!parent.empty() && !std::filesystem::is_directory(parent))
    throw std::runtime_error("control socket " + path + ": directory " + parent.string() +
                             " does not exist");
  const sockaddr_un addr = unix_address(path);
  replace_stale_socket(path);

  const int fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
  if (fd < 0)
    throw std::runtime_error("control socket " + path + ": socket(): " + errno_text(errno));
  auto fail = [&](const std::string& what) {
    const int err = errno;
    ::close(fd);
    throw std::runtime_error("control socket " + path + ": " + what + ": " + errno_text(err));
  };
  if (::bind(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) != 0) fail("bind");
  if (::chown(path.c_str(), static_cast<uid_t>(-1), group_id_) != 0) {
    const int err = errno;
    ::unlink(path.c_str());
    ::close(fd);
    throw std::runtime_error("control socket " + path + ": giving it to group '" + group_name_ +
                             "': " + errno_text(err));
  }
  if (::chmod(path.c_str(), static_cast<mode_t>(options_.socket_mode)) != 0) {
    ::unlink(path.c_str());
    fail("chmod");
  }
  if (::listen(fd, 64) != 0) {
    ::unlink(path.c_str());
    fail("listen");
  }
  wake_fd_ = ::eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK);
  if (wake_fd_ < 0) {
    ::unlink(path.c_str());
    fail("eventfd");
  }
  listen_fd_ = fd;
  running_ = true;
  if (!options_.database_path.empty())
    exports_ = std::make_unique<ExportStreams>(options_.database_path, options_.max_exports,
                                               options_.idle_timeout);
  // Two: a second diagnosis is refused by the controller, naming the run being diagnosed.
  diagnoses_ = std::make_unique<ConnectionThreads>(2, "diagnoses");
  thread_ = std::thread([this] { loop(); });
  spdlog::info("control socket listening on {} (mode 0{:o}, control group '{}')", path,
               options_.socket_mode, group_name_);
}

void ControlServer::stop() {
  if (!running_.exchange(false)) return;
  const std::uint64_t one = 1;
  if (::write(wake_fd_, &one, sizeof one) < 0) {
    // The loop also re-checks running_ on every wake-up; a full eventfd cannot happen here.
  }
  if (thread_.joinable()) thread_.join();
  if (exports_) exports_->stop_all();
  if (diagnoses_) diagnoses_->stop_all();
  ::close(listen_fd_);
  ::close(wake_fd_);
  listen_fd_ = wake_fd_ = -1;
  ::unlink(options_.socket_path.c_str());
}

ControlServerStats ControlServer::stats() const {
  ControlServerStats s;
  {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    s = stats_;
  }
  if (exports_) s.exports = exports_->active();
  return s;
}

bool ControlServer::permitted(const Client& client) const {
  return peer_in_group(client.cred.uid, client.cred.gid, group_id_);
}

void ControlServer::check_allowed(const Client& client, const Request& r) {
  if (needs_control_permission(r.cmd) && !permitted(client)) {
    {
      std::lock_guard<std::mutex> lock(stats_mutex_);
      ++stats_.permission_denied;
    }
    spdlog::warn("control: {} refused for {} (uid {}, pid {}): not in group '{}'", r.cmd,
                 client.user, client.cred.uid, client.cred.pid, group_name_);
    throw ControlError(error_code::kPermissionDenied,
                       r.cmd + " needs membership of the control group '" + group_name_ + "' (" +
                           client.user + " is not a member)");
  }
}

json ControlServer::dispatch(Client& client, const Request& r) {
  check_allowed(client, r);
  const json& a = r.args;
  if (r.cmd == cmd::kPing) return {{"version", options_.version}};
  if (r.cmd == cmd::kRunStart) {
    StartRunRequest s;
    if (a.contains("serial")) s.serial = a.at("serial").get<std::string>();
    if (a.contains("units"))
      for (const auto& u : a.at("units"))
        s.units.push_back({u.value("slot", std::string()), u.at("serial").get<std::string>()});
    if (a.contains("sequence")) s.sequence = a.at("sequence").get<std::string>();
    s.operator_name = a.contains("operator") && !a.at("operator").get<std::string>().empty()
                          ? a.at("operator").get<std::string>()
                          : client.user;
    std::string serials = s.serial;
    for (const auto& u : s.units) serials += (serials.empty() ? "" : ", ") + u.serial;
    spdlog::info("control: run.start serial {} by {} (uid {})", serials, client.user,
                 client.cred.uid);
    return handler_.start_run(s);
  }
  if (r.cmd == cmd::kRunStatus) {
    std::optional<db::history::RunId> id;
    if (a.contains("run_id")) id = a.at("run_id").get<db::history::RunId>();
    return handler_.status(id);
  }
  if (r.cmd == cmd::kRunAbort) {
    std::string reason = a.contains("reason") ? a.at("reason").get<std::string>() : "";
    if (reason.empty()) reason = "aborted by " + client.user;
    spdlog::info("control: run.abort by {} (uid {}): {}", client.user, client.cred.uid, reason);
    return handler_.abort_run(reason);
  }
  if (r.cmd == cmd::kReprocess) {
    ReprocessRequest q;
    q.run_id = a.at("run_id").get<db::history::RunId>();
    q.user = client.user;
    q.allow_partial = a.value("partial", false);
    if (a.contains("gravity_mps2")) q.gravity_mps2 = a.at("gravity_mps2").get<double>();
    spdlog::info("control: reprocess run {} by {} (uid {}){}{}", q.run_id, client.user,
                 client.cred.uid, q.allow_partial ? ", partial archive allowed" : "",
                 q.gravity_mps2 ? ", surveyed gravity " + std::to_string(*q.gravity_mps2) : "");
    return handler_.reprocess(q);
  }
  if (r.cmd == cmd::kImport) {
    const std::string dir = a.at("dir").get<std::string>();
    spdlog::info("control: import {} by {} (uid {})", dir, client.user, client.cred.uid);
    return handler_.import_archive(dir, client.user);
  }
  if (r.cmd == cmd::kPromote) {
    const auto id = a.at("run_id").get<db::history::RunId>();
    spdlog::info("control: promote run {} by {} (uid {})", id, client.user, client.cred.uid);
    return handler_.promote(id, client.user, a.at("reason").get<std::string>());
  }
  if (is_repository_read(r.cmd)) return answer_repository_read(handler_.repository(), r);
  throw ControlError(error_code::kInternal, "command " + r.cmd + " has no dispatcher");
}

/// The connection goes to a thread of the export streams (a copy of its descriptor); the loop
/// closes its own copy and reads no further requests from it.
void ControlServer::hand_over_export(Client& client, const Request& r) {
  if (!exports_)
    throw ControlError(error_code::kUnavailable,
                       "streamed exports are not available here (no database path)");
  const int fd = ::fcntl(client.fd, F_DUPFD_CLOEXEC, 0);
  if (fd < 0) throw ControlError(error_code::kUnavailable, "export: " + errno_text(errno));
  try {
    exports_->start(fd, r, client.user);
  } catch (...) {
    ::close(fd);
    throw;
  }
  client.in.clear();
  client.close_after_write = true;
}

/// Like an export: the connection goes to a thread that computes the diagnosis (seconds for an
/// hour's run) and writes its one reply; the loop serves the other clients meanwhile (issue #22).
/// The group check is the dispatcher's, done here before the hand-over.
void ControlServer::hand_over_diagnose(Client& client, const Request& r) {
  check_allowed(client, r);
  const auto run_id = r.args.at("run_id").get<db::history::RunId>();
  spdlog::info("control: diagnose run {} by {}", run_id, client.user);
  const int fd = ::fcntl(client.fd, F_DUPFD_CLOEXEC, 0);
  if (fd < 0) throw ControlError(error_code::kUnavailable, "diagnose: " + errno_text(errno));
  try {
    diagnoses_->start(fd, [this, id = r.id, run_id](int conn) {
      send_computed_reply(
          conn, id, [&] { return handler_.diagnose(run_id); }, options_.idle_timeout);
    });
  } catch (...) {
    ::close(fd);
    throw;
  }
  client.in.clear();
  client.close_after_write = true;
}

void ControlServer::serve_line(Client& client, std::string_view line) {
  json id = nullptr;
  json reply;
  try {
    const Request r = parse_request(line);
    id = r.id;
    if ((r.cmd == cmd::kExport && r.args.value("stream", false)) || r.cmd == cmd::kDiagnose) {
      if (r.cmd == cmd::kDiagnose)
        hand_over_diagnose(client, r);
      else
        hand_over_export(client, r);
      std::lock_guard<std::mutex> lock(stats_mutex_);
      ++stats_.requests;
      return;
    }
    reply = ok_reply(id, dispatch(client, r));
  } catch (const BadRequest& e) {
    {
      std::lock_guard<std::mutex> lock(stats_mutex_);
      ++stats_.bad_requests;
    }
    reply = error_reply(e.id(), e.code(), e.what());
  } catch (const ControlError& e) {
    reply = error_reply(id, e.code(), e.what());
  } catch (const db::history::DbError& e) {
    reply = error_reply(id, error_code_for(e.kind()), e.what());
  } catch (const std::exception& e) {
    spdlog::error("control: internal error answering {} from {}: {}", id.dump(), client.user,
                  e.what());
    reply = error_reply(id, error_code::kInternal, std::string("internal error: ") + e.what());
  }
  std::string line_out = reply_line(reply);
  reply = nullptr;  // large results (export) are freed before the line is queued
  if (client.out.empty())
    client.out = std::move(line_out);
  else
    client.out += line_out;
  std::lock_guard<std::mutex> lock(stats_mutex_);
  ++stats_.requests;
}

/// Sends what is pending and serves complete request lines, one reply at a time (so the output
/// buffer holds at most one reply), until the socket would block or no complete line is left.
void ControlServer::pump(Client& c) {
  for (;;) {
    if (c.out_pos < c.out.size()) {
      const ssize_t w = ::send(c.fd, c.out.data() + c.out_pos, c.out.size() - c.out_pos,
                               MSG_NOSIGNAL | MSG_DONTWAIT);
      if (w < 0) {
        if (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR) return;  // POLLOUT later
        ::close(c.fd);
        c.dead = true;
        return;
      }
      c.out_pos += static_cast<std::size_t>(w);
      c.last_traffic = std::chrono::steady_clock::now();
      if (c.out_pos < c.out.size()) return;
      c.out.clear();
      c.out_pos = 0;
    }
    if (c.close_after_write) {
      ::close(c.fd);
      c.dead = true;
      return;
    }
    const std::size_t nl = c.in.find('\n');
    if (nl != std::string::npos) {
      std::string line = c.in.substr(0, nl);
      c.in.erase(0, nl + 1);
      if (!line.empty() && line.back() == '\r') line.pop_back();
      if (line.find_first_not_of(" \t") == std::string::npos) continue;  // blank line
      serve_line(c, line);
      continue;
    }
    if (c.in.size() > kMaxLineBytes) {
      c.out = reply_line(error_reply(nullptr, error_code::kBadRequest,
                                     "request line exceeds the limit of " +
                                         std::to_string(kMaxLineBytes) +
                                         " bytes; closing the connection"));
      c.in.clear();
      c.close_after_write = true;
      std::lock_guard<std::mutex> lock(stats_mutex_);
      ++stats_.oversize_closed;
      ++stats_.bad_requests;
      continue;
    }
    if (c.eof) {
      // End of stream: an unterminated last line is still a request; answer it, then close.
      if (c.in.find_first_not_of(" \t\r") != std::string::npos) {
        std::string line = std::move(c.in);
        c.in.clear();
        serve_line(c, line);
      }
      c.close_after_write = true;
      continue;
    }
    return;
  }
}

/// Until the earliest idle deadline (at least 10 ms, so a burst of idle closes is not a spin).
int ControlServer::poll_timeout_ms(const std::list<Client>& clients) const {
  if (clients.empty()) return -1;
  auto earliest = std::chrono::steady_clock::time_point::max();
  for (const auto& c : clients) earliest = std::min(earliest, c.last_traffic);
  const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
      earliest + options_.idle_timeout - std::chrono::steady_clock::now());
  return static_cast<int>(std::clamp<std::int64_t>(left.count() + 1, 10, 60000));
}

/// Closes every connection without traffic for idle_timeout: an idle client holds a slot, a
/// client that does not read its reply holds a slot and a buffer.
void ControlServer::close_idle(std::list<Client>& clients) {
  const auto now = std::chrono::steady_clock::now();
  for (auto& c : clients) {
    if (c.dead || now - c.last_traffic < options_.idle_timeout) continue;
    spdlog::info("control: closing the idle connection of {} (pid {}) after {} s", c.user,
                 c.cred.pid, options_.idle_timeout.count() / 1000.0);
    ::close(c.fd);
    c.dead = true;
    std::lock_guard<std::mutex> lock(stats_mutex_);
    ++stats_.idle_closed;
  }
}

/// A new connection over the total or the per-user limit gets one error reply and is closed.
void ControlServer::refuse_if_over_limits(const std::list<Client>& clients, Client& c) {
  std::string why;
  if (clients.size() >= options_.max_clients) {
    why = "too many control connections (" + std::to_string(options_.max_clients) + ")";
  } else if (c.cred.uid != 0 && c.cred.uid != ::getuid()) {
    std::size_t mine = 0;
    for (const auto& o : clients)
      if (!o.dead && !o.close_after_write && o.cred.uid == c.cred.uid) ++mine;
    if (mine >= options_.max_clients_per_user) {
      why = "too many control connections from " + c.user + " (" +
            std::to_string(options_.max_clients_per_user) + "); close some and retry";
      std::lock_guard<std::mutex> lock(stats_mutex_);
      ++stats_.per_user_refused;
    }
  }
  if (why.empty()) return;
  spdlog::warn("control: refusing a connection of {} (pid {}): {}", c.user, c.cred.pid, why);
  c.out = reply_line(error_reply(nullptr, error_code::kUnavailable, why));
  c.close_after_write = true;
}

void ControlServer::loop() {
  std::list<Client> clients;
  std::vector<pollfd> fds;
  std::vector<Client*> order;
  std::vector<char> chunk(kReadChunk);
  while (running_) {
    fds.clear();
    order.clear();
    fds.push_back({wake_fd_, POLLIN, 0});
    fds.push_back({listen_fd_, POLLIN, 0});
    for (auto& c : clients) {
      short events = 0;
      // Backpressure: no new requests are read from a client while a reply to it is pending.
      if (c.out_pos < c.out.size())
        events = POLLOUT;
      else if (!c.close_after_write)
        events = POLLIN;
      fds.push_back({c.fd, events, 0});
      order.push_back(&c);
    }
    const int n = ::poll(fds.data(), fds.size(), poll_timeout_ms(clients));
    if (n < 0) {
      if (errno == EINTR) continue;
      spdlog::error("control socket: poll: {}", errno_text(errno));
      break;
    }
    if (fds[0].revents) break;  // stop()
    if (fds[1].revents & POLLIN) accept_pending(clients);
    for (std::size_t i = 0; i < order.size(); ++i)
      if (fds[i + 2].revents) serve_ready(*order[i], fds[i + 2].revents, chunk);
    close_idle(clients);
    clients.remove_if([](const Client& c) { return c.dead; });
    std::lock_guard<std::mutex> lock(stats_mutex_);
    stats_.clients = clients.size();
  }
  for (auto& c : clients)
    if (!c.dead) ::close(c.fd);
  std::lock_guard<std::mutex> lock(stats_mutex_);
  stats_.clients = 0;
}

/// Every queued connection, with its peer's credentials (none: no control), refused when over the
/// per-user or total limits.
void ControlServer::accept_pending(std::list<Client>& clients) {
  for (;;) {
    const int cfd = ::accept4(listen_fd_, nullptr, nullptr, SOCK_CLOEXEC | SOCK_NONBLOCK);
    if (cfd < 0) {
      if (errno == EMFILE || errno == ENFILE) {
        // Out of descriptors: the pending connection stays queued and the listening socket
        // stays readable; pause instead of spinning until a client hangs up.
        spdlog::warn("control socket: accept: {}", errno_text(errno));
        std::this_thread::sleep_for(std::chrono::milliseconds(100));
      } else if (errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR) {
        spdlog::warn("control socket: accept: {}", errno_text(errno));
      }
      return;
    }
    Client c;
    c.fd = cfd;
    socklen_t len = sizeof c.cred;
    if (::getsockopt(cfd, SOL_SOCKET, SO_PEERCRED, &c.cred, &len) != 0) {
      // Without credentials no one may control the station: an id that matches no group.
      c.cred.uid = static_cast<uid_t>(-1);
      c.cred.gid = static_cast<gid_t>(-1);
      c.cred.pid = 0;
    }
    c.user = user_name_of(c.cred.uid);
    {
      std::lock_guard<std::mutex> lock(stats_mutex_);
      ++stats_.connections;
    }
    refuse_if_over_limits(clients, c);
    clients.push_back(std::move(c));
  }
}

/// A client the poll found ready: its reply's socket gone, or new bytes (or its end) read; then
/// pump it (requests answered, replies written). An exception drops this client only.
void ControlServer::serve_ready(Client& c, short re, std::vector<char>& chunk) {
  if (re & POLLNVAL) {
    c.dead = true;
    return;
  }
  if (c.out_pos < c.out.size()) {
    if (re & (POLLERR | POLLHUP) && !(re & POLLOUT)) {
      ::close(c.fd);
      c.dead = true;
      return;
    }
  } else if (re & (POLLIN | POLLHUP | POLLERR)) {
    const ssize_t r = ::recv(c.fd, chunk.data(), chunk.size(), MSG_DONTWAIT);
    if (r < 0) {
      if (errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR) {
        ::close(c.fd);
        c.dead = true;
      }
      return;
    }
    if (r == 0) {
      c.eof = true;
    } else {
      c.in.append(chunk.data(), static_cast<std::size_t>(r));
      c.last_traffic = std::chrono::steady_clock::now();
    }
  }
  try {
    pump(c);
  } catch (const std::exception& e) {
    // E.g. out of memory building a reply: this client is dropped, the others go on.
    spdlog::error("control: dropping the connection of {} (pid {}): {}", c.user, c.cred.pid,
                  e.what());
    if (!c.dead) ::close(c.fd);
    c.dead = true;
  }
}

}  // namespace imucal::station::control
