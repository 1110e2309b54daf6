// stationd: the calibration station daemon (its guides: docs/integrator.md, docs/operator.md).
//
//   stationd --config FILE [--check-config] [--log-level L]
//
// Exit codes: 0 clean stop (SIGTERM/SIGINT) or config ok; 1 start-up or runtime failure (database,
// socket, ...); 2 bad command line or bad configuration (one line "FILE:LINE:COL: message" on
// stderr, nothing created).
#include <malloc.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <csignal>
#include <iostream>

#include "db/fleet/fleet_schema.hpp"
#include "db/history/sqlite_repository.hpp"
#include "station/config/config.hpp"
#include "station/daemon/daemon.hpp"
#include "station/daemon/fleet_sender.hpp"
#include "station/daemon/logging.hpp"
#include "station/daemon/sd_notify.hpp"

namespace {

/// --check-config with [fleet]: can this station log in to its fleet store, and is the store's
/// schema one this software can write? The daemon itself starts either way (the line never stops
/// for the fleet store); this is the check before deployment. 0 ok, 1 not.
int check_fleet(const imucal::station::config::FleetConfig& fleet) {
  namespace fl = imucal::db::fleet;
  if (!fleet.password_file.empty()) {
    const std::string exposed = fl::password_file_exposure(fleet.password_file);
    if (!exposed.empty()) std::cerr << "warning: " << exposed << "\n";
  }
  try {
    const fl::FleetTarget target = imucal::station::daemon::fleet_target(fleet);
    fl::PgConnection c(target);
    const int v = fl::fleet_version(c);
    if (v > fl::kFleetSchemaVersion) fl::check_fleet_version(c);  // throws: newer than ours
    std::cout << "fleet store " << target.redacted() << ": ok (station id " << fleet.station_id
              << ", schema "
              << (v == 0 ? std::string("none yet: the daemon creates it")
                         : "version " + std::to_string(v) +
                               (v < fl::kFleetSchemaVersion ? ", the daemon migrates it" : ""))
              << ")\n";
    return 0;
  } catch (const imucal::db::history::DbError& e) {
    std::cerr << "fleet store: " << e.what()
              << "\n(stationd would start anyway and keep the changes in its outbox)\n";
    return 1;
  }
}

}  // namespace

int main(int argc, char** argv) {
  // One malloc arena for the whole daemon, set before any thread starts: a calibration allocates
  // its sample arrays on up to three threads (archive read, the two methods), and with glibc's
  // default of one arena per thread up to 8 per core, each arena kept its own high-water mark —
  // the resident size crept up by tens of MB over a soak of 15 runs. Allocation is not on any hot
  // path here (measured: `imucal bench` unchanged with MALLOC_ARENA_MAX=1).
  mallopt(M_ARENA_MAX, 1);
  // SQLite's heap bounded for the whole process, with the per-connection page cache: the one place
  // for its limits and their measurement is db/history/sqlite_repository.hpp.
  imucal::db::history::limit_sqlite_process_memory();
  using namespace imucal::station;
  using namespace imucal::station::config;
  using namespace imucal::station::daemon;
  CLI::App app{"stationd " IMUCAL_VERSION " — IMU calibration station daemon"};
  std::string config_path, log_level;
  bool check_only = false;
  app.add_option("--config", config_path, "station configuration file (TOML)")->required();
  app.add_flag("--check-config", check_only, "check the configuration file and exit");
  app.add_option("--log-level", log_level, "override [log] level")
      ->check(CLI::IsMember({"trace", "debug", "info", "warn", "error", "critical", "off"}));
  app.set_version_flag("--version", IMUCAL_VERSION);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int rc = app.exit(e);
    return rc == 0 ? 0 : 2;
  }

  StationConfig cfg;
  try {
    cfg = load_config(config_path);
  } catch (const ConfigError& e) {
    std::cerr << e.what() << "\n";
    return 2;
  }
  if (!log_level.empty()) cfg.log_level = log_level;
  if (check_only) {
    std::string imus;  // "IMU unixcan:..." or "IMUs A unixcan:..., B ..."
    for (const auto& slot : cfg.imus)
      imus += (imus.empty() ? "" : ", ") + (cfg.imus.size() > 1 ? slot.name + " " : std::string()) +
              slot.can_uri;
    std::cout << config_path << ": ok (station " << cfg.station_name << ", table "
              << cfg.turntable.endpoint.to_string() << (cfg.imus.size() > 1 ? ", IMUs " : ", IMU ")
              << imus << ", data " << cfg.data_dir << ", socket " << cfg.control_socket << ")\n";
    return cfg.fleet ? check_fleet(*cfg.fleet) : 0;
  }

  setup_logging(cfg.log_level);
  std::signal(SIGPIPE, SIG_IGN);  // a client that hangs up must not kill the daemon
  try {
    DaemonOptions opt;
    opt.notifier = SdNotifier::from_environment();
    Daemon daemon(cfg, opt);
    return daemon.run();
  } catch (const std::exception& e) {
    spdlog::critical("{}", e.what());
    if (spdlog::default_logger()->sinks().empty()) std::cerr << "stationd: " << e.what() << "\n";
    return 1;
  }
}
