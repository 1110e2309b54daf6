#include "tools/stationctl/export_cmd.hpp"

#include <chrono>
#include <iostream>
#include <optional>
#include <string_view>

#include "db/history/export.hpp"
#include "db/history/export_per_run.hpp"
#include "db/history/sqlite_repository.hpp"
#include "station/control/record_json.hpp"
#include "tools/stationctl/export_output.hpp"

namespace imucal::tools::stationctl {

namespace {

using station::control::ControlClientError;

/// A streamed export: the longest wait for its next frame (the daemon sends one per 64 KiB).
constexpr auto kExportFrameTimeout = std::chrono::seconds(30);

/// export's request arguments, checked here as the daemon would check them.
json export_args(const ExportArgs& a) {
  json args = {{"format", a.format}};
  if (a.per_run) args["per_run"] = true;
  if (!a.station.empty()) args["station"] = a.station;
  if (!a.serial.empty()) {
    check_serial(a.serial);
    args["serial"] = a.serial;
  }
  if (!a.since.empty()) {
    try {
      (void)db::history::parse_time_utc(a.since);
    } catch (const db::history::DbError& e) {
      throw Failure{kBadInput, std::string("--since: ") + e.what()};
    }
    args["since"] = a.since;
  }
  return args;
}

/// A database error while exporting: the output's own failure, with the system's reason, before
/// the export's words.
[[noreturn]] void export_failed(const ExportOutput& out, const db::history::DbError& e) {
  out.check();
  throw Failure{exit_for_db_error(e.kind()), e.what()};
}

/// The rows of `repo` the arguments select, written to `out`; their number.
std::size_t export_rows(const db::history::Repository& repo, const json& args, ExportOutput& out) {
  return db::history::export_in_shape(repo, station::control::export_filter(repo, args),
                                      args.at("format").get<std::string>(),
                                      args.value("per_run", false), out.stream());
}

/// The export read from the fleet store (--fleet URL).
std::size_t export_from_fleet(const Target& t, const json& args, ExportOutput& out) {
  const auto repo = open_fleet(t);
  try {
    return export_rows(*repo, args, out);
  } catch (const db::history::DbError& e) {
    export_failed(out, e);
  }
}

/// The export streamed from the daemon into `out`; the rows, or nullopt (with `why`) when the
/// daemon cannot serve it and nothing has been written yet, so the database can be read instead.
std::optional<std::size_t> export_from_daemon(const Target& t, const json& args, ExportOutput& out,
                                              std::string& why) {
  using Kind = ControlClientError::Kind;
  std::optional<ControlClient> client = connect_for_read(t, why);
  if (!client) return std::nullopt;
  bool wrote = false;
  try {
    json streamed = args;
    streamed["stream"] = true;
    const station::control::Reply r = client->call_streamed(
        station::control::cmd::kExport, streamed,
        [&](std::string_view bytes) {
          wrote = true;
          out.write(bytes);
        },
        kExportFrameTimeout);
    if (r.ok) return r.result.at("rows").get<std::size_t>();
    if (r.error_code != station::control::error_code::kUnavailable || t.db.empty() || wrote)
      result_or_fail(r);
    why = "stationd: " + r.error_message;
  } catch (const ControlClientError& e) {
    if (wrote || t.db.empty() || (e.kind() != Kind::kTimeout && e.kind() != Kind::kClosed))
      throw Failure{kUnavailable, e.what()};
    why = e.what();
  }
  return std::nullopt;
}

/// The export read from the database read-only, `why` the daemon did not serve it.
std::size_t export_from_database(const Target& t, const json& args, ExportOutput& out,
                                 const std::string& why) {
  announce_database_fallback(t, why);
  try {
    db::history::SqliteOptions options;
    options.read_only = true;
    const db::history::SqliteRepository repo(t.db, options);
    return export_rows(repo, args, out);
  } catch (const db::history::DbError& e) {
    export_failed(out, e);
  }
}

/// The export into `output` (standard output if empty); with an output file, what was written is
/// said on stderr, or as a JSON summary with --json.
int export_to(const Target& t, const json& args, const std::string& output, bool json_out) {
  ExportOutput out(output);
  std::string why;
  std::optional<std::size_t> rows;
  if (!t.fleet_url.empty())
    rows = export_from_fleet(t, args, out);
  else
    rows = export_from_daemon(t, args, out, why);
  if (!rows) rows = export_from_database(t, args, out, why);
  out.commit();
  if (output.empty()) return kOk;
  if (json_out)
    print_json({{"format", args.at("format")}, {"rows", *rows}, {"output", output}});
  else
    std::cerr << "stationctl: " << *rows << " rows written to " << output << "\n";
  return kOk;
}

}  // namespace

CLI::App* add_export_command(CLI::App& app, ExportArgs& a) {
  CLI::App* exp = app.add_subcommand(
      "export",
      "the history as CSV, JSON or NDJSON, streamed: a row (CSV) or object (JSON) per run and "
      "calibration method, so a factory run gives two, AINS and NLSQ, and a run without results "
      "one; --per-run gives one per run (with --json and --output: a JSON summary of what was "
      "written)");
  exp->add_option("--serial", a.serial, "only this unit");
  exp->add_option("--since", a.since, "only runs started at or after (YYYY-MM-DD[THH:MM[:SS]][Z])");
  exp->add_option("--format", a.format, "csv, json (one array) or ndjson (one object per line)")
      ->required()
      ->check(CLI::IsMember({"csv", "json", "ndjson"}));
  exp->add_option("--output", a.output, "write to FILE instead of stdout");
  exp->add_option("--station", a.station, "only this station's runs");
  exp->add_flag("--per-run", a.per_run,
                "one row per run: each method's columns side by side, prefixed ains., nlsq., "
                "legacy. (JSON: an object per run with its \"calibrations\")");
  exp->fallthrough();
  return exp;
}

int cmd_export(const Target& t, const ExportArgs& a, bool as_json) {
  const json args = export_args(a);
  try {
    return export_to(t, args, a.output, as_json);
  } catch (const ExportOutputError& e) {
    throw Failure{kUnavailable, e.what()};
  }
}

}  // namespace imucal::tools::stationctl
