#include "tools/stationweb/server.hpp"

#include <malloc.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <functional>

#include "tools/stationweb/html.hpp"
#include "tools/stationweb/page_limits.hpp"
#include "tools/stationweb/pages.hpp"

namespace imucal::tools::stationweb {

namespace {

constexpr const char* kHtml = "text/html; charset=utf-8";

const char* reason_phrase(int status) {
  switch (status) {
    case 400:
      return "Bad Request";
    case 404:
      return "Not Found";
    case 405:
      return "Method Not Allowed";
    case 503:
      return "Service Unavailable";
    default:
      return "Internal Server Error";
  }
}

void fail(httplib::Response& res, int status, const std::string& field,
          const std::string& message) {
  res.status = status;
  res.set_content(error_page(status, reason_phrase(status), field, message), kHtml);
}

/// Gives the heap's free pages back to the system after a large request (issue #52 item 5: the
/// server kept 1.78 GB resident after one page): glibc keeps freed memory in its arenas.
void return_memory(std::size_t body_bytes, double ms) {
  if (body_bytes > (256u << 10) || ms > 50) malloc_trim(0);
}

/// An error page keeps what the page offered (issue #52 item 10): the refusal's own links (a
/// suggested serial) and the request's parameters as a form to correct and send again.
void keep_request_form(const httplib::Request& req, httplib::Response& res, const PageError& e) {
  const auto* more = dynamic_cast<const PageErrorMore*>(&e);
  std::string extra = (more ? more->more_html : "") + request_form(req.path, req.params);
  const std::size_t at = res.body.rfind("\n</body>");
  if (!extra.empty() && at != std::string::npos) res.body.insert(at, "\n" + extra);
}

/// Renders a page into `res`, mapping its failures to statuses, with the source's notice on top
/// (a history file deleted or replaced under the server); logs the request and its time.
void respond(const httplib::Request& req, httplib::Response& res,
             const std::function<std::string()>& render,
             const std::function<std::string()>& notice = {}) {
  const auto t0 = std::chrono::steady_clock::now();
  try {
    std::string body = render();
    if (body.size() > kMaxPageBytes)
      throw PageError(400, "",
                      "This page would be " + std::to_string(body.size() >> 20) +
                          " MB, more than stationweb's limit of " +
                          std::to_string(kMaxPageBytes >> 20) +
                          " MB per page: narrow the window or the filters.");
    res.set_content(notice ? with_notice(std::move(body), notice()) : std::move(body), kHtml);
    res.status = 200;
  } catch (const PageError& e) {
    fail(res, e.status, e.field, e.what());
    keep_request_form(req, res, e);
  } catch (const db::history::Busy& e) {
    spdlog::warn("{} {}: {}", req.method, req.path, e.what());
    fail(res, 503, "", "The history is busy; try again in a moment.");
  } catch (const std::exception& e) {
    spdlog::error("{} {}: {}", req.method, req.path, e.what());
    fail(res, 500, "", std::string("The history could not be read: ") + e.what());
  }
  if (notice && res.status != 200) res.body = with_notice(std::move(res.body), notice());
  const double ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return_memory(res.body.size(), ms);
  spdlog::debug("{} {} {} {:.1f} ms", req.method, req.target, res.status, ms);
}

/// `text` as a header value: control characters (a line break would end the header) as blanks.
std::string header_safe(std::string text) {
  for (char& c : text)
    if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) c = ' ';
  return text;
}

using ReplyRender = std::function<Reply(const httplib::Request&)>;

/// A route that may answer data (?format=csv|json) as well as a page: rendered through respond
/// (its statuses and logging), then given the reply's media type and download name.
httplib::Server::Handler reply_handler(const History* h, ReplyRender render) {
  return [h, render = std::move(render)](const httplib::Request& req, httplib::Response& res) {
    Reply reply;
    respond(
        req, res,
        [&] {
          reply = render(req);
          return reply.body;
        },
        h->source_notice);  // with_notice leaves what is not a page (CSV, JSON) as it is
    if (res.status != 200) return;
    std::string body;
    body.swap(res.body);
    res.set_content(body, reply.content_type);
    // A download has no page to carry the notice (issue #52 item 11): a header says it, in plain
    // text (the notice names a file path, which may hold any byte but a line break).
    if (reply.content_type.rfind("text/html", 0) != 0)
      if (const std::string notice = h->source_notice(); !notice.empty())
        res.set_header("X-History-Notice", header_safe(notice));
    if (!reply.filename.empty())
      res.set_header("Content-Disposition", "attachment; filename=\"" + reply.filename + "\"");
  };
}

void method_not_allowed(const httplib::Request& req, httplib::Response& res) {
  spdlog::debug("{} {} refused: read-only view", req.method, req.path);
  res.set_header("Allow", "GET, HEAD");
  fail(res, 405, "",
       "stationweb is a read-only view: only GET and HEAD are served, not " + req.method + ".");
}

}  // namespace

void install_routes(httplib::Server& server, const History& history) {
  const History* h = &history;
  server.Get("/", reply_handler(
                      h, [h](const httplib::Request& req) { return index_reply(*h, req.params); }));
  server.Get("/unit", [](const httplib::Request& req, httplib::Response& res) {
    std::string serial;
    respond(req, res, [&] {
      serial = unit_search(req.params);
      return std::string();
    });
    if (res.status == 200) res.set_redirect("/unit/" + url_encode(serial), 303);
  });
  server.Get(R"(/unit/([^/]*))", reply_handler(h, [h](const httplib::Request& req) {
               return unit_reply(*h, req.matches[1].str(), req.params);
             }));
  server.Get(R"(/run/([^/]*))", reply_handler(h, [h](const httplib::Request& req) {
               return run_reply(*h, req.matches[1].str(), req.params);
             }));
  server.Get("/runs", reply_handler(h, [h](const httplib::Request& req) {
               return runs_reply(*h, req.params);
             }));
  server.Get("/compare", reply_handler(h, [h](const httplib::Request& req) {
               return compare_reply(*h, req.params);
             }));
  server.Get("/fleet", reply_handler(h, [h](const httplib::Request& req) {
               return fleet_reply(*h, req.params);
             }));
  server.Get("/signatures/trend", reply_handler(h, [h](const httplib::Request& req) {
               return signature_trend_reply(*h, req.params);
             }));
  server.Get("/signatures", reply_handler(h, [h](const httplib::Request& req) {
               return signatures_reply(*h, req.params);
             }));
  server.Post(".*", method_not_allowed);
  server.Put(".*", method_not_allowed);
  server.Patch(".*", method_not_allowed);
  server.Delete(".*", method_not_allowed);
  server.Options(".*", method_not_allowed);
  // Unknown paths (and our own error pages, which already have a body) end here.
  server.set_error_handler(httplib::Server::HandlerWithResponse([](const httplib::Request& req,
                                                                   httplib::Response& res) {
    if (!res.body.empty()) return httplib::Server::HandlerResponse::Unhandled;
    // A write the parser refused before routing (a POST without a body is a 400 there) is still
    // a write to a read-only view.
    if (req.method != "GET" && req.method != "HEAD" && !req.method.empty()) {
      method_not_allowed(req, res);
      return httplib::Server::HandlerResponse::Handled;
    }
    spdlog::debug("{} {} {}", req.method, req.path, res.status);
    fail(res, res.status, "", res.status == 404 ? "No page at " + req.path + "." : "Bad request.");
    return httplib::Server::HandlerResponse::Handled;
  }));
  server.set_payload_max_length(64 * 1024);  // nothing is uploaded to a read-only view
  // Headers and body go out in separate writes: without TCP_NODELAY the body waits for the
  // client's delayed ACK (40 ms on Linux) on a kept-alive connection.
  server.set_tcp_nodelay(true);
  // SO_REUSEADDR (a restart need not wait for TIME_WAIT) but not httplib's default SO_REUSEPORT,
  // with which a second process could bind the same port and take a share of the connections.
  server.set_socket_options([](socket_t sock) {
    int yes = 1;
    setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
  });
}

}  // namespace imucal::tools::stationweb
