#pragma once
// One GET of a running stationweb for the web tests: status (-1 when no answer), body, and the
// Content-Type and Location headers.
#include <string>

#include "tools/stationweb/httplib.hpp"

namespace imucal::test_support {

struct WebReply {
  int status = -1;
  std::string body, type, location;
};

inline WebReply web_get(int port, const std::string& target) {
  httplib::Client c("127.0.0.1", port);
  c.set_url_encode(false);
  c.set_read_timeout(30, 0);
  const auto r = c.Get(target.c_str());
  WebReply g;
  if (!r) return g;
  g.status = r->status;
  g.body = r->body;
  g.type = r->get_header_value("Content-Type");
  g.location = r->get_header_value("Location");
  return g;
}

}  // namespace imucal::test_support
