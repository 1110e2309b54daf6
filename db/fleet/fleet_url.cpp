#include "db/fleet/fleet_url.hpp"

#include <libpq-fe.h>
#include <sys/stat.h>

#include <cstdio>
#include <cstdlib>
#include <fstream>

#include "db/history/repository.hpp"

namespace imucal::db::fleet {
using namespace db::history;

namespace {

void replace_all(std::string& text, const std::string& what, const std::string& with) {
  if (what.empty()) return;
  for (std::size_t at = text.find(what); at != std::string::npos;
       at = text.find(what, at + with.size()))
    text.replace(at, what.size(), with);
}

/// The password libpq reads out of `url` (URI user:password@ or password=...), or "".
std::string password_in(const std::string& url) {
  char* err = nullptr;
  PQconninfoOption* opts = PQconninfoParse(url.c_str(), &err);
  if (err) PQfreemem(err);
  std::string password;
  for (PQconninfoOption* o = opts; o && o->keyword; ++o)
    if (std::string(o->keyword) == "password" && o->val) password = o->val;
  if (opts) PQconninfoFree(opts);
  return password;
}

/// libpq parses a port as text and complains only when it connects: check it here.
bool valid_port(const std::string& text) {
  if (text.empty() || text.size() > 5) return false;
  for (char ch : text)
    if (ch < '0' || ch > '9') return false;
  const int port = std::stoi(text);
  return port >= 1 && port <= 65535;
}

}  // namespace

std::string FleetTarget::redacted() const { return redact(url); }

std::string FleetTarget::redact(const std::string& text) const {
  std::string out = text;
  replace_all(out, password, "***");
  replace_all(out, password_in(url), "***");
  return out;
}

FleetTarget parse_fleet_target(const std::string& url, const std::string& password) {
  FleetTarget t{url, password};
  if (url.empty()) throw InvalidInput("fleet url: empty (expected postgresql://USER@HOST:PORT/DB)");
  char* err = nullptr;
  PQconninfoOption* opts = PQconninfoParse(url.c_str(), &err);
  if (!opts) {
    std::string reason = err ? err : "not a connection URL";
    if (err) PQfreemem(err);
    while (!reason.empty() && (reason.back() == '\n' || reason.back() == ' ')) reason.pop_back();
    // The reason may quote parts of the URL: scrub the password out of it, and the URL itself.
    throw InvalidInput("fleet url: " + t.redact(reason) +
                       " (expected postgresql://USER@HOST:PORT/DB)");
  }
  bool has_host = false;
  for (PQconninfoOption* o = opts; o->keyword; ++o) {
    const std::string key = o->keyword;
    if ((key == "host" || key == "hostaddr") && o->val && *o->val) has_host = true;
    if (key == "port" && o->val && *o->val && !valid_port(o->val)) {
      const std::string port = o->val;
      PQconninfoFree(opts);
      throw InvalidInput("fleet url: " + t.redacted() + ": port \"" + t.redact(port) +
                         "\" is not a number from 1 to 65535");
    }
  }
  PQconninfoFree(opts);
  if (!has_host)
    throw InvalidInput("fleet url: " + t.redacted() +
                       " names no host (expected postgresql://USER@HOST:PORT/DB)");
  return t;
}

std::string read_password_file(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InvalidInput("fleet password_file " + path + ": cannot be read");
  std::string line;
  std::getline(in, line);
  if (!line.empty() && line.back() == '\r') line.pop_back();
  if (line.empty()) throw InvalidInput("fleet password_file " + path + ": the first line is empty");
  return line;
}

std::string password_file_exposure(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0 || (st.st_mode & 077) == 0) return "";
  char mode[8];
  std::snprintf(mode, sizeof mode, "%04o", static_cast<unsigned>(st.st_mode & 07777));
  return "fleet password_file " + path + ": mode " + mode +
         " lets its group or others read the password; only its owner should (chmod 600 " + path +
         ")";
}

std::string read_password_env(const std::string& variable) {
  const char* v = std::getenv(variable.c_str());
  if (!v || !*v)
    throw InvalidInput("fleet password_env: the environment variable " + variable +
                       " is not set or empty");
  return v;
}

}  // namespace imucal::db::fleet
