#include "station/daemon/logging.hpp"

#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <stdexcept>
#ifdef IMUCAL_HAVE_LIBSYSTEMD
#include <spdlog/sinks/systemd_sink.h>
#endif

#include "station/config/config.hpp"

namespace imucal::station::daemon {
using namespace station::config;

bool stderr_is_journal() {
  const char* js = std::getenv("JOURNAL_STREAM");
  if (!js || !*js) return false;
  unsigned long long dev = 0, ino = 0;
  char tail = 0;
  if (std::sscanf(js, "%llu:%llu%c", &dev, &ino, &tail) != 2) return false;
  struct stat st {};
  if (fstat(STDERR_FILENO, &st) != 0) return false;
  return static_cast<unsigned long long>(st.st_dev) == dev &&
         static_cast<unsigned long long>(st.st_ino) == ino;
}

LogTarget setup_logging(const std::string& level, const std::string& ident) {
  if (!is_log_level(level)) throw std::invalid_argument("unknown log level \"" + level + "\"");
  std::shared_ptr<spdlog::logger> logger;
  LogTarget target = LogTarget::kConsole;
#ifdef IMUCAL_HAVE_LIBSYSTEMD
  if (stderr_is_journal()) {
    // The journal stores time, pid and priority itself: the message goes unformatted.
    auto sink = std::make_shared<spdlog::sinks::systemd_sink_mt>(ident, false);
    logger = std::make_shared<spdlog::logger>(ident, sink);
    target = LogTarget::kJournal;
  }
#endif
  if (!logger) {
    auto sink = std::make_shared<spdlog::sinks::stderr_color_sink_mt>();
    logger = std::make_shared<spdlog::logger>(ident, sink);
    logger->set_pattern("%Y-%m-%dT%H:%M:%S.%e %^%-5l%$ [%t] %v");
  }
  logger->set_level(spdlog::level::from_str(level));
  logger->flush_on(spdlog::level::warn);
  spdlog::set_default_logger(logger);
  return target;
}

}  // namespace imucal::station::daemon
