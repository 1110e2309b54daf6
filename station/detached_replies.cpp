#include "station/detached_replies.hpp"

#include <fcntl.h>
#include <spdlog/spdlog.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include <cerrno>
#include <string>

#include "db/repository.hpp"
#include "station/control_handler.hpp"
#include "station/control_protocol.hpp"

namespace imucal::station {

void make_blocking_with_send_timeout(int fd, std::chrono::milliseconds timeout) {
  const int flags = ::fcntl(fd, F_GETFL);
  if (flags >= 0) ::fcntl(fd, F_SETFL, flags & ~O_NONBLOCK);
  timeval tv{};
  tv.tv_sec = static_cast<time_t>(timeout.count() / 1000);
  tv.tv_usec = static_cast<suseconds_t>((timeout.count() % 1000) * 1000);
  ::setsockopt(fd, SOL_SOCKET, SO_SNDTIMEO, &tv, sizeof tv);
}

namespace {

/// The reply to send: the answer, or the error reply for what computing it threw.
nlohmann::json reply_for(const nlohmann::json& id, const std::function<nlohmann::json()>& answer) {
  try {
    return ok_reply(id, answer());
  } catch (const ControlError& e) {
    return error_reply(id, e.code(), e.what());
  } catch (const db::DbError& e) {
    return error_reply(id, error_code_for(e.kind()), e.what());
  } catch (const std::exception& e) {
    spdlog::error("control: internal error answering {}: {}", id.dump(), e.what());
    return error_reply(id, error_code::kInternal, std::string("internal error: ") + e.what());
  }
}

void send_all(int fd, const std::string& line) {
  std::size_t at = 0;
  while (at < line.size()) {
    const ssize_t w = ::send(fd, line.data() + at, line.size() - at, MSG_NOSIGNAL);
    if (w < 0 && errno == EINTR) continue;
    if (w <= 0) return;  // the client went away or stopped reading: nobody to tell
    at += static_cast<std::size_t>(w);
  }
}

}  // namespace

DetachedReplies::DetachedReplies(std::size_t max_concurrent, std::chrono::milliseconds send_timeout)
    : max_concurrent_(max_concurrent), send_timeout_(send_timeout) {}

DetachedReplies::~DetachedReplies() { stop_all(); }

void DetachedReplies::join_finished() {
  for (auto it = tasks_.begin(); it != tasks_.end();) {
    if ((*it)->done) {
      (*it)->thread.join();
      it = tasks_.erase(it);
    } else {
      ++it;
    }
  }
}

void DetachedReplies::start(int fd, const nlohmann::json& id,
                            std::function<nlohmann::json()> answer) {
  std::lock_guard<std::mutex> lock(mutex_);
  join_finished();
  if (stopping_) throw ControlError(error_code::kUnavailable, "the daemon is stopping");
  if (tasks_.size() >= max_concurrent_)
    throw ControlError(
        error_code::kBusy,
        std::to_string(max_concurrent_) + " such requests are running; retry when one has ended");
  auto t = std::make_unique<Task>();
  Task* raw = t.get();
  raw->fd = fd;
  make_blocking_with_send_timeout(fd, send_timeout_);
  raw->thread = std::thread([this, raw, id, answer = std::move(answer)] {
    // Only this thread closes the descriptor, under the lock: stop_all() shuts down the
    // descriptors of running tasks, never a number that was closed and reused meanwhile.
    send_all(raw->fd, reply_line(reply_for(id, answer)));
    std::lock_guard<std::mutex> done_lock(mutex_);
    ::close(raw->fd);
    raw->fd = -1;
    raw->done = true;
  });
  tasks_.push_back(std::move(t));
}

void DetachedReplies::stop_all() {
  std::list<std::unique_ptr<Task>> stopping;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
    for (auto& t : tasks_)
      if (t->fd >= 0) ::shutdown(t->fd, SHUT_RDWR);
    stopping.swap(tasks_);
  }
  for (auto& t : stopping) t->thread.join();  // unlocked: each thread takes the lock to finish
}

std::size_t DetachedReplies::active() const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::size_t n = 0;
  for (const auto& t : tasks_) n += t->done ? 0 : 1;
  return n;
}

}  // namespace imucal::station
