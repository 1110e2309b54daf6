#include "station/control/export_stream.hpp"

#include <fcntl.h>
#include <spdlog/spdlog.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <ostream>
#include <streambuf>
#include <vector>

#include "db/history/export.hpp"
#include "db/history/export_per_run.hpp"
#include "db/history/sqlite_repository.hpp"
#include "station/control/control_handler.hpp"
#include "station/control/record_json.hpp"

namespace imucal::station::control {

namespace {

using json = nlohmann::json;
using Clock = std::chrono::steady_clock;

/// Writes the export as frames ("<hex length>\n<bytes>") on a blocking socket. A failed send (the
/// client went away, stopped reading past the send timeout, or the daemon stops) makes every
/// further write fail, which the ostream reports to the exporter as a failed stream.
class FrameWriter : public std::streambuf {
 public:
  FrameWriter(int fd, const std::atomic<bool>& stopping)
      : fd_(fd), stopping_(stopping), buffer_(ExportStreams::kFrameBytes) {
    setp(buffer_.data(), buffer_.data() + buffer_.size());
  }

  /// One protocol line (the header or the trailer), outside any frame.
  bool send_line(const std::string& line) { return send_all(line.data(), line.size()); }
  /// The last frame: "0\n".
  bool end_frames() { return flush_frame() && send_all("0\n", 2); }
  bool failed() const { return failed_; }
  const std::string& why() const { return why_; }

 protected:
  int overflow(int c) override {
    if (!flush_frame()) return traits_type::eof();
    if (c != traits_type::eof()) {
      *pptr() = static_cast<char>(c);
      pbump(1);
    }
    return traits_type::not_eof(c);
  }
  int sync() override { return flush_frame() ? 0 : -1; }

 private:
  bool flush_frame() {
    const std::size_t n = static_cast<std::size_t>(pptr() - pbase());
    if (n == 0) return !failed_;
    char head[24];
    const int h = std::snprintf(head, sizeof head, "%zx\n", n);
    const bool ok = send_all(head, static_cast<std::size_t>(h)) && send_all(pbase(), n);
    setp(buffer_.data(), buffer_.data() + buffer_.size());
    return ok;
  }

  bool send_all(const char* data, std::size_t size) {
    while (size > 0 && !failed_) {
      if (stopping_) return fail("the daemon is stopping");
      const ssize_t w = ::send(fd_, data, size, MSG_NOSIGNAL);
      if (w > 0) {
        data += w;
        size -= static_cast<std::size_t>(w);
      } else if (w < 0 && errno == EINTR) {
        continue;
      } else if (w < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
        return fail("the client stopped reading (send timeout)");
      } else {
        return fail(std::string("the client went away (") + std::strerror(errno) + ")");
      }
    }
    return !failed_;
  }
  bool fail(std::string why) {
    failed_ = true;
    why_ = std::move(why);
    return false;
  }

  int fd_;
  const std::atomic<bool>& stopping_;
  std::vector<char> buffer_;
  bool failed_ = false;
  std::string why_;
};

/// The error reply for what an export threw.
json error_reply_for(const json& id, const std::exception& e) {
  if (const auto* d = dynamic_cast<const db::history::DbError*>(&e))
    return error_reply(id, error_code_for(d->kind()), d->what());
  return error_reply(id, error_code::kInternal, std::string("internal error: ") + e.what());
}

/// The whole life of one streamed export: header, frames, last frame, trailer (the caller closes
/// `fd`).
void stream_export(int fd, const Request& request, const std::string& user,
                   const std::string& database_path, std::chrono::milliseconds send_timeout,
                   const std::atomic<bool>& stopping) {
  const auto t0 = Clock::now();
  const std::string format = request.args.at("format").get<std::string>();
  make_blocking_with_send_timeout(fd, send_timeout);
  FrameWriter frames(fd, stopping);
  bool header_sent = false;
  std::size_t rows = 0;
  json trailer;
  try {
    db::history::SqliteOptions options;
    options.read_only = true;
    const db::history::SqliteRepository repo(database_path, options);
    const db::history::ExportFilter filter = export_filter(repo, request.args);
    header_sent =
        frames.send_line(reply_line(ok_reply(request.id, {{"format", format}, {"stream", true}})));
    if (header_sent) {
      std::ostream out(&frames);
      rows = db::history::export_in_shape(repo, filter, format,
                                          request.args.value("per_run", false), out);
      trailer = ok_reply(request.id, {{"format", format}, {"rows", rows}});
    }
  } catch (const std::exception& e) {
    trailer = error_reply_for(request.id, e);
  }
  const double seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  if (frames.failed()) {
    spdlog::warn("control: streamed {} export for {} ended after {:.1f} s: {}", format, user,
                 seconds, frames.why());
  } else {
    if (header_sent) frames.end_frames();
    frames.send_line(reply_line(trailer));
    if (trailer.value("ok", false))
      spdlog::info("control: streamed {} export for {}: {} rows in {:.1f} s", format, user, rows,
                   seconds);
  }
}

}  // namespace

ExportStreams::ExportStreams(std::string database_path, std::size_t max_concurrent,
                             std::chrono::milliseconds send_timeout)
    : database_path_(std::move(database_path)),
      send_timeout_(send_timeout),
      threads_(max_concurrent, "exports") {}

void ExportStreams::start(int fd, const Request& request, const std::string& user) {
  threads_.start(fd, [this, request, user](int conn) {
    stream_export(conn, request, user, database_path_, send_timeout_, threads_.stopping());
  });
}

}  // namespace imucal::station::control
