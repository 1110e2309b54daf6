#pragma once
// stationd's logging: spdlog's default logger, to the systemd journal when the daemon runs as a
// systemd service (its stderr is the journal stream, see below), to the console otherwise.
//
// systemd sets $JOURNAL_STREAM to "DEVICE:INODE" of the stream it connected to stdout/stderr;
// systemd.exec(5) says to compare it with fstat(2) of stderr rather than trust its mere presence
// (a child started from a service inherits the variable but maybe not the stream). When it matches
// and the build has libsystemd (IMUCAL_HAVE_LIBSYSTEMD), records go through sd_journal with their
// priority and SYSLOG_IDENTIFIER; otherwise to stderr with time, level and thread.
#include <string>

namespace imucal::station::daemon {

enum class LogTarget { kConsole, kJournal };

/// True if $JOURNAL_STREAM names this process's stderr.
bool stderr_is_journal();

/// Installs the default logger (name "stationd") at `level` (config.hpp's words). Returns where the
/// records go. Throws std::invalid_argument for an unknown level.
LogTarget setup_logging(const std::string& level, const std::string& ident = "stationd");

}  // namespace imucal::station::daemon
