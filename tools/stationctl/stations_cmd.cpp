#include "tools/stationctl/stations_cmd.hpp"

#include <cstdio>
#include <iostream>
#include <memory>

#include "db/fleet/pg_fleet_stats.hpp"
#include "db/history/sqlite_fleet_stats.hpp"
#include "db/history/sqlite_repository.hpp"
#include "tools/report/station_signatures.hpp"

namespace imucal::tools::stationctl {

namespace {

/// One station's runs by whose their end was (issue #50): the unit's own outcomes and its yield,
/// and the station's faults, aborts and interrupted runs apart.
json station_counts_json(const db::history::StationVerdictCounts& v) {
  json o = {{"station", v.station},
            {"runs", v.total()},
            {"pass", v.pass},
            {"review", v.review},
            {"failed", v.failed},
            {"unit_outcomes", v.unit_outcomes()},
            {"station_faults", v.station_fault},
            {"aborted", v.aborted},
            {"interrupted", v.interrupted},
            {"live", v.live}};
  o["unit_yield"] = v.unit_outcomes() > 0
                        ? json(static_cast<double>(v.pass) / static_cast<double>(v.unit_outcomes()))
                        : json(nullptr);
  return o;
}

std::string station_counts_text(const json& s) {
  std::string line = text(s, "station") + "  " + text(s, "runs") + " runs: " + text(s, "pass") +
                     " PASS, " + text(s, "review") + " REVIEW, " + text(s, "failed") +
                     " FAILED of " + text(s, "unit_outcomes") + " the units decided";
  if (!s["unit_yield"].is_null()) {
    char pct[32];
    std::snprintf(pct, sizeof pct, " (yield %.1f %%)", 100.0 * s["unit_yield"].get<double>());
    line += pct;
  }
  return line + "; " + text(s, "station_faults") + " station fault(s), " + text(s, "aborted") +
         " aborted, " + text(s, "interrupted") + " interrupted, " + text(s, "live") + " live";
}

/// `stationctl [--fleet URL | --db FILE] stations`: the stations with runs, each with its units'
/// outcomes and its own faults counted apart, by /fleet's rule (factory runs unless --setting says
/// otherwise; one capture once).
int list_stations(const Target& t, const StationsArgs& a, bool as_json) {
  if (t.fleet_url.empty() && t.db.empty())
    throw Failure{kBadInput, "stations: give the fleet store with --fleet URL, or --db"};
  json list = json::array();
  try {
    std::unique_ptr<db::history::FleetStats> stats;
    if (!t.fleet_url.empty())
      stats = std::make_unique<db::fleet::PgFleetStats>(
          db::fleet::parse_fleet_target(t.fleet_url, t.fleet_password));
    else
      stats = std::make_unique<db::history::SqliteFleetStats>(t.db);
    db::history::FleetFilter filter;
    if (a.setting != "all") filter.setting = a.setting;
    for (const auto& v : stats->verdict_counts_per_station(filter))
      list.push_back(station_counts_json(v));
  } catch (const db::history::DbError& e) {
    throw Failure{exit_for_db_error(e.kind()), e.what()};
  }
  const std::string counted =
      (a.setting == "all" ? std::string("runs of every setting") : a.setting + " runs") +
      ", one capture once (a reprocessed run is stood for by its newest reprocess)";
  if (as_json) {
    print_json({{"setting", a.setting}, {"counted", counted}, {"stations", list}});
  } else {
    std::cout << "counted: " << counted << "\n";
    for (const json& s : list) std::cout << station_counts_text(s) << "\n";
    if (list.empty()) std::cout << "no station has stored runs\n";
  }
  return kOk;
}

/// What the signatures are computed from: the fleet store, else the database read-only.
struct SignatureSources {
  std::unique_ptr<db::history::Repository> repo;
  std::unique_ptr<db::history::FleetStats> stats;
};

SignatureSources open_signature_sources(const Target& t) {
  SignatureSources s;
  if (!t.fleet_url.empty()) {
    const auto target = db::fleet::parse_fleet_target(t.fleet_url, t.fleet_password);
    s.repo = std::make_unique<db::fleet::FleetRepository>(target);
    s.stats = std::make_unique<db::fleet::PgFleetStats>(target);
  } else {
    db::history::SqliteOptions ro;
    ro.read_only = true;
    s.repo = std::make_unique<db::history::SqliteRepository>(t.db, ro);
    s.stats = std::make_unique<db::history::SqliteFleetStats>(t.db);
  }
  return s;
}

/// Progress of a long signature computation on stderr.
void say_progress(const std::string& line) { std::cerr << line << "...\n"; }

/// `stations --signatures --trend`: the signatures period by period; exit 1 if a station is
/// flagged in the newest period (an old flag is history).
int signature_trend(const SignatureSources& s, const StationsArgs& a,
                    const calib::studies::fleet::SignatureOptions& options, bool as_json) {
  const db::history::FleetFilter window =
      tools::report::signature_window(*s.repo, a.since, a.until, 12 * a.period_days);
  json trend = tools::report::station_signature_trend(*s.stats, window, a.period_days, options,
                                                      say_progress);
  bool flagged_now = false;
  if (!trend["periods"].empty())
    for (const json& st : trend["periods"].back()["stations"])
      flagged_now = flagged_now || st.value("flagged", false);
  if (as_json)
    print_json(trend);
  else
    std::cout << tools::report::render_signature_trend_text(trend);
  return flagged_now ? kRunNotPassed : kOk;
}

/// `stations --signatures`: the signatures over one window; exit 1 if a station is flagged.
int signature_report(const SignatureSources& s, const StationsArgs& a,
                     const calib::studies::fleet::SignatureOptions& options, bool as_json) {
  const db::history::FleetFilter window =
      tools::report::signature_window(*s.repo, a.since, a.until);
  json report = tools::report::station_signature_report(*s.stats, window, options, say_progress);
  report["since"] = window.since_ms ? db::history::format_time_utc(*window.since_ms) : "";
  report["until"] = window.until_ms ? db::history::format_time_utc(*window.until_ms) : "";
  bool flagged = false;
  for (const json& st : report["stations"]) flagged = flagged || st.value("flagged", false);
  if (as_json)
    print_json(report);
  else
    std::cout << "runs started " << text(report, "since") << " until " << text(report, "until")
              << "\n"
              << tools::report::render_signatures_text(report);
  return flagged ? kRunNotPassed : kOk;
}

/// `stationctl [--fleet URL | --db FILE] stations --signatures`: station signatures (issue #25).
int station_signatures(const Target& t, const StationsArgs& a, bool as_json) {
  if (t.fleet_url.empty() && t.db.empty())
    throw Failure{kBadInput, "stations --signatures: give the fleet store (--fleet URL) or --db"};
  try {
    const SignatureSources sources = open_signature_sources(t);
    calib::studies::fleet::SignatureOptions options;
    options.false_alarm = a.false_alarm;
    if (a.trend) return signature_trend(sources, a, options, as_json);
    return signature_report(sources, a, options, as_json);
  } catch (const tools::report::WindowError& e) {
    throw Failure{kBadInput, std::string("stations --signatures: ") + e.what()};
  } catch (const db::history::DbError& e) {
    throw Failure{exit_for_db_error(e.kind()), e.what()};
  }
}

}  // namespace

CLI::App* add_stations_command(CLI::App& app, StationsArgs& a) {
  CLI::App* stations = app.add_subcommand(
      "stations",
      "the stations with runs in the fleet store (--fleet URL) or --db, each with its units' "
      "outcomes and its own faults (station faults, aborts, interrupted) counted apart; or their "
      "signatures");
  stations->add_flag("--signatures", a.signatures,
                     "each station's departure from the fleet and the station errors it fits "
                     "(issue #25), from the fleet store or --db; exit 1 if one is flagged");
  stations->add_option("--since", a.since,
                       "signatures: runs started at or after (UTC date or time; default: 7 "
                       "days before --until)");
  stations->add_option("--until", a.until,
                       "signatures: runs started before (UTC date: up to the end of that day; "
                       "default: the end of the newest run's day)");
  stations->add_flag("--trend", a.trend,
                     "signatures period by period (default window: the 12 periods up to the "
                     "newest run's day); exit 1 if one is flagged in the newest period");
  stations->add_option("--period-days", a.period_days, "trend: the length of a period in days")
      ->check(CLI::Range(1, 366))
      ->default_val(7);
  stations
      ->add_option("--false-alarm", a.false_alarm,
                   "signatures: false-alarm rate per station and period")
      ->check(CLI::Range(1e-6, 0.2))
      ->default_val(1e-3);
  stations
      ->add_option("--setting", a.setting,
                   "the list: the runs of this setting (factory, land, sea or all), as "
                   "stationweb's /fleet?setting= counts them")
      ->check(CLI::IsMember({"factory", "land", "sea", "all"}))
      ->default_val("factory");
  stations->fallthrough();
  return stations;
}

int cmd_stations(const Target& t, const StationsArgs& a, bool as_json) {
  return a.signatures || a.trend ? station_signatures(t, a, as_json) : list_stations(t, a, as_json);
}

}  // namespace imucal::tools::stationctl
