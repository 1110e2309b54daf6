#pragma once
// Where the fleet store is and how to log in (issue #24 item 1): `[fleet] url =
// "postgresql://user@host:port/db"`, the password from a file (`password_file`, first line) or an
// environment variable (`password_env`), never from the log. A password inside the URL is accepted
// but discouraged; every text this module produces for people (redacted()) replaces it with "***",
// and redact() scrubs it from any message (libpq's own included).
#include <string>

namespace imucal::db::fleet {

struct FleetTarget {
  std::string url;       ///< as configured (may hold a password: never print it)
  std::string password;  ///< from password_file / password_env, or empty (libpq's own sources)
  /// The URL with any password replaced by "***" (what messages, `status` and logs show).
  std::string redacted() const;
  /// `text` with the password (from either source) replaced by "***".
  std::string redact(const std::string& text) const;
};

/// Checks the URL with libpq's own parser (postgresql:// or postgres:// URIs, or key=value
/// connection strings) and returns its target. Throws db::history::InvalidInput "fleet url:
/// <reason>" (the reason redacted) for anything libpq would refuse, and for a URL with no host (a
/// fleet store is a server, never a local default).
FleetTarget parse_fleet_target(const std::string& url, const std::string& password = {});

/// The password from a file (its first line, without the newline) or an environment variable.
/// Throws db::history::InvalidInput naming the file or variable (never its content) if unreadable
/// or empty.
std::string read_password_file(const std::string& path);
std::string read_password_env(const std::string& variable);

/// "" if only its owner may read or write the password file, else a warning naming the file, its
/// mode and the remedy (chmod 600): group or others could read the fleet store's password (libpq
/// ignores a ~/.pgpass so exposed). Also "" for a file that cannot be examined (reading it
/// reports).
std::string password_file_exposure(const std::string& path);

}  // namespace imucal::db::fleet
