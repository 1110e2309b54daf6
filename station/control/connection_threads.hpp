#pragma once
// Requests the control socket's poll loop hands over with their connection (issue #22): a
// streamed export, a gap diagnosis (seconds of CPU for an hour's run). Each runs on a thread of its
// own with a copy of the connection's descriptor, which it owns and which is closed when its work
// returns; the loop serves the other clients meanwhile. At most max_concurrent run; one more is
// refused (busy) without touching its connection. stop_all() shuts the connections down (a
// blocked send returns at once) and joins the threads.
#include <atomic>
#include <chrono>
#include <cstddef>
#include <functional>
#include <list>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>

namespace imucal::station::control {

/// A handed-over connection as its thread wants it: blocking sends that give up after `timeout`
/// (the descriptor shares its flags with the poll loop's copy, which closes that copy at once).
void make_blocking_with_send_timeout(int fd, std::chrono::milliseconds timeout);

class ConnectionThreads {
 public:
  /// `what` names the requests in the busy refusal ("exports", "diagnoses").
  ConnectionThreads(std::size_t max_concurrent, std::string what);
  ~ConnectionThreads();  ///< stop_all()
  ConnectionThreads(const ConnectionThreads&) = delete;
  ConnectionThreads& operator=(const ConnectionThreads&) = delete;

  /// Runs work(fd) on a thread of its own; `fd` is taken over and closed after it. ControlError
  /// busy when max_concurrent run already, unavailable once stopping: `fd` is then the caller's.
  void start(int fd, std::function<void(int fd)> work);
  void stop_all();
  std::size_t active() const;
  /// Set by stop_all(): long work (an export's frames) ends early.
  const std::atomic<bool>& stopping() const { return stopping_; }

 private:
  struct Task {
    int fd = -1;
    std::thread thread;
    std::atomic<bool> done{false};
  };
  void join_finished();  ///< with mutex_ held

  std::size_t max_concurrent_;
  std::string what_;
  mutable std::mutex mutex_;
  std::list<std::unique_ptr<Task>> tasks_;
  std::atomic<bool> stopping_{false};
};

/// One reply computed on a handed-over connection: answer()'s result, or the error reply for
/// what it threw (ControlError, DbError, anything else as internal), written as one line.
void send_computed_reply(int fd, const nlohmann::json& id,
                         const std::function<nlohmann::json()>& answer,
                         std::chrono::milliseconds send_timeout);

}  // namespace imucal::station::control
