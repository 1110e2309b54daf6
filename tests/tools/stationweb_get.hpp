#pragma once
// The web tests' stationweb: which binary serves (stationweb_under_test), and one GET of it
// (status, -1 when no answer; body; the Content-Type and Location headers).
#include <cstdlib>
#include <string>

#include "tools/stationweb/httplib.hpp"

namespace imucal::test_support {

struct WebReply {
  int status = -1;
  std::string body, type, location;
};

/// The stationweb a web test serves its history with: build/bin/stationweb, or
/// $IMUCAL_STATIONWEB_BIN (another build, e.g. one from before a fix, which the test must fail on).
inline std::string stationweb_under_test() {
  const char* bin = std::getenv("IMUCAL_STATIONWEB_BIN");
  return bin && *bin ? bin : std::string(IMUCAL_BIN_DIR) + "/stationweb";
}

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
