#pragma once
// Requests that take long (a gap diagnosis of an hour's run: seconds of CPU) answered off the
// control socket's poll loop (issue #22 item 3): the connection is handed over, as a streamed
// export's is, to a thread of its own that computes the one reply, writes it with a blocking send
// (given up after send_timeout) and closes the connection. Other clients are served meanwhile. At
// most max_concurrent such requests run; one more is refused (busy) without touching its
// connection.
#include <atomic>
#include <chrono>
#include <cstddef>
#include <functional>
#include <list>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <thread>

namespace imucal::station {

/// A handed-over connection as its thread wants it: blocking sends that give up after `timeout`
/// (the descriptor shares its flags with the poll loop's copy, which closes that copy at once).
void make_blocking_with_send_timeout(int fd, std::chrono::milliseconds timeout);

class DetachedReplies {
 public:
  DetachedReplies(std::size_t max_concurrent, std::chrono::milliseconds send_timeout);
  ~DetachedReplies();  ///< stop_all()
  DetachedReplies(const DetachedReplies&) = delete;
  DetachedReplies& operator=(const DetachedReplies&) = delete;

  /// Answers request `id` on `fd` (taken over, closed when done) with `answer()`'s result, or
  /// with the error reply for what it threw (ControlError, DbError, anything else as internal).
  /// ControlError(busy) when max_concurrent run already; `fd` is then left to the caller.
  void start(int fd, const nlohmann::json& id, std::function<nlohmann::json()> answer);
  /// Shuts down the connections of running requests and joins their threads (a computation
  /// still running is waited for; its reply goes nowhere).
  void stop_all();
  std::size_t active() const;

 private:
  struct Task {
    int fd = -1;
    std::thread thread;
    std::atomic<bool> done{false};
  };
  void join_finished();  ///< with mutex_ held

  std::size_t max_concurrent_;
  std::chrono::milliseconds send_timeout_;
  mutable std::mutex mutex_;
  std::list<std::unique_ptr<Task>> tasks_;
  bool stopping_ = false;
};

}  // namespace imucal::station
