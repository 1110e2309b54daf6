#pragma once
// stationweb's HTTP routes on a cpp-httplib server: GET (and HEAD) of the pages of
// tools/stationweb/pages.hpp; every other method 405 with "Allow: GET, HEAD"; an unknown path 404.
// A page's PageError becomes its status (400 naming the field, 404) with an error page; a database
// failure 503 (busy) or 500, logged. Nothing a user types can make a 500: input is checked before
// the database is asked.
#include "tools/stationweb/history_source.hpp"
#include "tools/stationweb/httplib.hpp"

namespace imucal::tools::stationweb {

/// Installs the routes and the server's socket options (TCP_NODELAY; SO_REUSEADDR, never
/// SO_REUSEPORT: a port in use is refused); `history` must outlive the server.
void install_routes(httplib::Server& server, const History& history);

}  // namespace imucal::tools::stationweb
