#pragma once
// The daemon's control socket: a listening AF_UNIX stream socket served by one thread with a poll
// loop over all clients (ARCHITECTURE §2.1, step 2; protocol in control_protocol.hpp).
//
// Per request line: validate (bad_request naming the field), check permission for run.start,
// run.abort and reprocess, then dispatch — to the ControlHandler for the run commands and
// run.status, to record_json.hpp's answer_repository_read(handler.repository()) for history, show,
// params and export, and ping is answered here ({"version": ...}). A streamed export is handed to
// an ExportStreams thread with the connection (export_stream.hpp): the poll loop is done with it.
//
// Permission: the peer's credentials are read with SO_PEERCRED when it connects. uid 0 is allowed;
// otherwise the peer must be in the control group — as its primary gid, or by the group list of its
// user (getgrouplist of the passwd entry of its uid). A refusal is permission_denied and names the
// group; the handler is not called. Reads need no membership of the group, but the socket file
// mode decides who may connect at all: 0660 by default (owner and control group); everyone else
// reads the history database directly (stationctl falls back to it).
//
// Robustness: one client's garbage gets that client an error reply and nothing else; a line longer
// than kMaxLineBytes gets an error reply and that connection is closed (the rest of the line cannot
// be told from the next request); a client that stops reading stalls only itself (its requests are
// not read while a reply to it is pending, so its buffers stay bounded). A connection that neither
// sends nor reads for idle_timeout is closed (idle and slow clients cannot pile up), and one user
// (uid) holds at most max_clients_per_user connections (root and the daemon's own uid exempt), so
// no single account can lock the operators out.
//
// Threading: the handler is only ever called from the server thread, one request at a time, so two
// clients never run handler code concurrently. A slow handler call delays the other clients'
// replies (by design: the daemon's handler methods return quickly and leave the work to its own
// threads). The handler may of course be called by the daemon's other threads too; making that safe
// is the handler's business.
#include <sys/types.h>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <list>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "station/control/connection_threads.hpp"
#include "station/control/control_handler.hpp"
#include "station/control/control_protocol.hpp"
#include "station/control/export_stream.hpp"

namespace imucal::station::control {

struct ControlServerOptions {
  std::string socket_path;      ///< parent directory must exist; a stale socket file is replaced
  std::string group;            ///< control group name; "" = the daemon's primary group
  unsigned socket_mode = 0660;  ///< file mode of the socket (chmod after bind)
  std::string version = IMUCAL_VERSION;   ///< answered by ping
  std::size_t max_clients = 128;          ///< more concurrent connections are refused (unavailable)
  std::size_t max_clients_per_user = 16;  ///< per peer uid (root and the daemon's uid exempt)
  /// A connection with no traffic either way for this long is closed (a pending reply the client
  /// does not read counts as no traffic).
  std::chrono::milliseconds idle_timeout{60000};
  /// The history database, for streamed exports (export_stream.hpp), each of which reads it on a
  /// connection of its own; "" = streamed exports are refused (unavailable).
  std::string database_path;
  std::size_t max_exports = 4;  ///< streamed exports at a time; more are refused (busy)
};

struct ControlServerStats {
  std::uint64_t connections = 0;        ///< accepted, in total
  std::uint64_t requests = 0;           ///< lines answered
  std::uint64_t bad_requests = 0;       ///< bad_request replies
  std::uint64_t permission_denied = 0;  ///< refused control commands
  std::uint64_t oversize_closed = 0;    ///< connections closed for a line over the limit
  std::uint64_t idle_closed = 0;        ///< connections closed after idle_timeout
  std::uint64_t per_user_refused = 0;   ///< connections refused over max_clients_per_user
  std::size_t clients = 0;              ///< connected now
  std::size_t exports = 0;              ///< streamed exports running now (own threads)
};

class ControlServer {
 public:
  ControlServer(ControlHandler& handler, ControlServerOptions options);
  ~ControlServer();  ///< stop()
  ControlServer(const ControlServer&) = delete;
  ControlServer& operator=(const ControlServer&) = delete;

  /// Resolves the group, binds and listens (chmod to socket_mode, chown to the group), then starts
  /// the thread: clients can connect when this returns. std::runtime_error naming the path or group
  /// if the parent directory is missing, the path is too long, another process listens there, the
  /// path is something other than a socket, or the group does not exist.
  void start();
  /// Closes every connection, stops the thread and removes the socket file. Idempotent.
  void stop();

  const std::string& socket_path() const { return options_.socket_path; }
  const std::string& group_name() const { return group_name_; }
  gid_t group_id() const { return group_id_; }
  ControlServerStats stats() const;

 private:
  struct Client;
  void loop();
  /// loop()'s steps: accept every pending connection; read from one ready client and pump it.
  void accept_pending(std::list<Client>& clients);
  void serve_ready(Client& client, short revents, std::vector<char>& chunk);
  void pump(Client& client);
  void serve_line(Client& client, std::string_view line);
  int poll_timeout_ms(const std::list<Client>& clients) const;
  void close_idle(std::list<Client>& clients);
  void refuse_if_over_limits(const std::list<Client>& clients, Client& client);
  nlohmann::json dispatch(Client& client, const Request& request);
  void hand_over_export(Client& client, const Request& request);
  /// Refuses (permission denied, counted and logged) a control command from a non-member.
  void check_allowed(const Client& client, const Request& request);
  /// A diagnosis is answered by a thread of its own on the handed-over connection.
  void hand_over_diagnose(Client& client, const Request& request);
  bool permitted(const Client& client) const;

  ControlHandler& handler_;
  ControlServerOptions options_;
  std::string group_name_;
  gid_t group_id_ = 0;
  int listen_fd_ = -1;
  int wake_fd_ = -1;  ///< eventfd: stop() wakes the poll loop
  std::thread thread_;
  std::unique_ptr<ExportStreams> exports_;
  std::unique_ptr<ConnectionThreads> diagnoses_;
  std::atomic<bool> running_{false};
  mutable std::mutex stats_mutex_;
  ControlServerStats stats_;
};

/// Whether a process with these credentials may use the control commands on a socket whose control
/// group is `group`: uid 0, primary gid == group, or group in getgrouplist(<user of uid>).
bool peer_in_group(uid_t uid, gid_t gid, gid_t group);
/// The user name of a uid ("uid N" when it has no passwd entry).
std::string user_name_of(uid_t uid);

}  // namespace imucal::station::control
