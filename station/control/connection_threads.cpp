#include "station/control/connection_threads.hpp"

#include <fcntl.h>
#include <spdlog/spdlog.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include <cerrno>

#include "db/history/repository.hpp"
#include "station/control/control_handler.hpp"
#include "station/control/control_protocol.hpp"

namespace imucal::station::control {

void make_blocking_with_send_timeout(int fd, std::chrono::milliseconds timeout) {
  const int flags = ::fcntl(fd, F_GETFL);
  if (flags >= 0) ::fcntl(fd, F_SETFL, flags & ~O_NONBLOCK);
  timeval tv{};
  tv.tv_sec = static_cast<time_t>(timeout.count() / 1000);
  tv.tv_usec = static_cast<suseconds_t>((timeout.count() % 1000) * 1000);
  ::setsockopt(fd, SOL_SOCKET, SO_SNDTIMEO, &tv, sizeof tv);
}

ConnectionThreads::ConnectionThreads(std::size_t max_concurrent, std::string what)
    : max_concurrent_(max_concurrent), what_(std::move(what)) {}

ConnectionThreads::~ConnectionThreads() { stop_all(); }

void ConnectionThreads::join_finished() {
  for (auto it = tasks_.begin(); it != tasks_.end();) {
    if ((*it)->done) {
      (*it)->thread.join();
      it = tasks_.erase(it);
    } else {
      ++it;
    }
  }
}

void ConnectionThreads::start(int fd, std::function<void(int fd)> work) {
  std::lock_guard<std::mutex> lock(mutex_);
  join_finished();
  if (stopping_) throw ControlError(error_code::kUnavailable, "the daemon is stopping");
  if (tasks_.size() >= max_concurrent_)
    throw ControlError(error_code::kBusy, std::to_string(max_concurrent_) + " " + what_ +
                                              " are running; retry when one has ended");
  auto t = std::make_unique<Task>();
  Task* raw = t.get();
  raw->fd = fd;
  raw->thread = std::thread([this, raw, work = std::move(work)] {
    work(raw->fd);
    // Only this thread closes the descriptor, under the lock: stop_all() shuts down the
    // descriptors of running tasks, never a number that was closed and reused meanwhile.
    std::lock_guard<std::mutex> done_lock(mutex_);
    ::close(raw->fd);
    raw->fd = -1;
    raw->done = true;
  });
  tasks_.push_back(std::move(t));
}

void ConnectionThreads::stop_all() {
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

std::size_t ConnectionThreads::active() const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::size_t n = 0;
  for (const auto& t : tasks_) n += t->done ? 0 : 1;
  return n;
}

namespace {

nlohmann::json reply_for(const nlohmann::json& id, const std::function<nlohmann::json()>& answer) {
  try {
    return ok_reply(id, answer());
  } catch (const ControlError& e) {
    return error_reply(id, e.code(), e.what());
  } catch (const db::history::DbError& e) {
    return error_reply(id, error_code_for(e.kind()), e.what());
  } catch (const std::exception& e) {
    spdlog::error("control: internal error answering {}: {}", id.dump(), e.what());
    return error_reply(id, error_code::kInternal, std::string("internal error: ") + e.what());
  }
}

}  // namespace

void send_computed_reply(int fd, const nlohmann::json& id,
                         const std::function<nlohmann::json()>& answer,
                         std::chrono::milliseconds send_timeout) {
  make_blocking_with_send_timeout(fd, send_timeout);
  const std::string line = reply_line(reply_for(id, answer));
  std::size_t at = 0;
  while (at < line.size()) {
    const ssize_t w = ::send(fd, line.data() + at, line.size() - at, MSG_NOSIGNAL);
    if (w < 0 && errno == EINTR) continue;
    if (w <= 0) return;  // the client went away or stopped reading: nobody to tell
    at += static_cast<std::size_t>(w);
  }
}

}  // namespace imucal::station::control
