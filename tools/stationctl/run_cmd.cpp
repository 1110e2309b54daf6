#include "tools/stationctl/run_cmd.hpp"

#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <iostream>
#include <optional>
#include <thread>

#include "db/history/serial_number.hpp"
#include "station/control/record_json.hpp"

namespace imucal::tools::stationctl {

namespace {

constexpr auto kPollPeriod = std::chrono::milliseconds(200);
/// A run.status the daemon does not answer in this time counts as a daemon that stopped answering.
constexpr auto kRunStatusTimeout = std::chrono::seconds(30);
/// While the daemon does not answer, --wait asks again after 0.25 s, then twice as long each time
/// up to 4 s: a restarted daemon is seen within 4 s, a dead one costs a connect attempt per 4 s.
constexpr auto kOutageFirstRetry = std::chrono::milliseconds(250);
constexpr auto kOutageLongestRetry = std::chrono::milliseconds(4000);
/// How long --wait waits for a daemon that stopped answering before it gives up (exit 4): by
/// default 10 minutes, long enough for systemd to restart it, or for a person to
/// (`run start --give-up-after S`).
std::chrono::duration<double> g_outage_limit{600.0};

/// Set by SIGINT/SIGTERM while --wait follows a run: stop following (the run itself goes on).
std::atomic<bool> g_stop_following{false};
extern "C" void on_stop_signal(int) { g_stop_following = true; }

void stop_following_on_signals() {
  struct sigaction sa {};
  sa.sa_handler = on_stop_signal;
  sigemptyset(&sa.sa_mask);
  ::sigaction(SIGINT, &sa, nullptr);
  ::sigaction(SIGTERM, &sa, nullptr);
}

bool state_done_pass(const json& run) {
  return text(run, "state") == "done" && text(run, "verdict") == "PASS";
}

/// --wait's exit code for a run that ended: 0 done + PASS, 5 interrupted (its daemon stopped;
/// not the unit's doing), 1 any other end.
int exit_for_outcome(const json& run) {
  if (state_done_pass(run)) return kOk;
  return text(run, "state") == "interrupted" ? kRunInterrupted : kRunNotPassed;
}

bool is_terminal_state(const std::string& state) {
  return state == "done" || state == "review" || state == "failed" || state == "aborted" ||
         state == "interrupted";
}

/// The progress line of a followed run on stderr: on a TTY rewritten in place, otherwise a new
/// line only when step, phase or state changes.
class ProgressLine {
 public:
  void show(const json& run) {
    const std::string line = station::control::progress_line(run);
    if (tty_) {
      if (line != last_line_) {
        std::string out = "\r" + line;
        if (line.size() < shown_width_) out += std::string(shown_width_ - line.size(), ' ');
        std::cerr << out << std::flush;
        shown_width_ = line.size();
        last_line_ = line;
      }
    } else {
      // Time left changes every poll; a log gets a line per step, phase or state only.
      const std::string key = text(run, "state") + "|" + text(run, "phase") + "|" +
                              (run.contains("step") ? run["step"].dump() : "");
      if (key != last_key_) {
        std::cerr << line << "\n" << std::flush;
        last_key_ = key;
      }
    }
  }
  /// Ends the line shown so far (keeping it) before a message of its own.
  void end_line() {
    if (tty_ && shown_width_) std::cerr << "\n";
    shown_width_ = 0;
  }
  /// On a TTY the progress line is wiped: the outcome replaces it.
  void wipe() {
    if (tty_ && shown_width_)
      std::cerr << "\r" << std::string(shown_width_, ' ') << "\r" << std::flush;
  }

 private:
  const bool tty_ = ::isatty(STDERR_FILENO) != 0;
  std::string last_key_, last_line_;
  std::size_t shown_width_ = 0;
};

/// Sleeps `period`, or less when a signal stops the following.
void pause_unless_stopped(std::chrono::milliseconds period) {
  const auto until = std::chrono::steady_clock::now() + period;
  while (!g_stop_following && std::chrono::steady_clock::now() < until)
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
}

/// The run as a daemon answering on a fresh connection reports it; that connection replaces
/// `client`. nullopt while nobody answers.
std::optional<json> run_from_returned_daemon(const Target& target, ControlClient& client,
                                             db::history::RunId run_id) {
  try {
    ControlClient fresh(target.socket);
    const station::control::Reply r =
        fresh.call(station::control::cmd::kRunStatus, {{"run_id", run_id}}, kRunStatusTimeout);
    const json status = result_or_fail(r);
    client = std::move(fresh);
    if (status.contains("run") && status["run"].is_object()) return status["run"];
    throw Failure{kUnavailable, "run.status reply without a run object: " + status.dump()};
  } catch (const station::control::ControlClientError&) {
    return std::nullopt;  // not back yet (or starting: it recovers before it listens)
  }
}

/// The daemon stopped answering while run `run_id` was followed (killed, crashed, stopped, hung):
/// said once, then the daemon is asked again with back-off until it answers — a restarted daemon
/// has marked the run interrupted (station/run/recovery.hpp) before it listens — while the
/// database is read quietly for an end the daemon recorded as it stopped (a SIGTERM aborts the
/// run). The run as then known; nullopt if a signal stopped the following; a Failure after
/// g_outage_limit of silence.
std::optional<json> follow_through_outage(const Target& target, ControlClient& client,
                                          db::history::RunId run_id, const std::string& why) {
  const std::string id = std::to_string(run_id);
  std::cerr << "stationctl: stationd stopped answering while following run " << id << " (" << why
            << "); waiting for it to come back (Ctrl-C stops waiting; the run's state: "
            << "`stationctl run status --run " << id << "`)\n"
            << std::flush;
  const auto give_up =
      std::chrono::steady_clock::now() +
      std::chrono::duration_cast<std::chrono::steady_clock::duration>(g_outage_limit);
  auto delay = kOutageFirstRetry;
  while (!g_stop_following) {
    if (auto run = run_from_returned_daemon(target, client, run_id)) return run;
    if (auto run = run_from_database(target, run_id); run && is_terminal_state(text(*run, "state")))
      return run;
    if (std::chrono::steady_clock::now() >= give_up)
      throw Failure{kUnavailable, "stationd has not answered for " +
                                      station::control::format_duration_s(g_outage_limit.count()) +
                                      " while following run " + id + " (" + why +
                                      "); the run's state: `stationctl run status --run " + id +
                                      "`"};
    pause_unless_stopped(delay);
    delay = std::min(delay * 2, kOutageLongestRetry);
  }
  return std::nullopt;
}

/// The followed run as the daemon reports it now; when the daemon has stopped answering, as it is
/// once the daemon answers again (or the database shows its end). nullopt if a signal stopped the
/// following meanwhile.
std::optional<json> poll_run(const Target& target, ControlClient& client, db::history::RunId run_id,
                             ProgressLine& progress) {
  using Kind = station::control::ControlClientError::Kind;
  json status;
  try {
    status = result_or_fail(
        client.call(station::control::cmd::kRunStatus, {{"run_id", run_id}}, kRunStatusTimeout));
  } catch (const station::control::ControlClientError& e) {
    if (e.kind() == Kind::kProtocol) throw Failure{kUnavailable, e.what()};
    progress.end_line();  // keep the last progress shown
    return follow_through_outage(target, client, run_id, e.what());
  }
  if (!status.contains("run") || !status["run"].is_object())
    throw Failure{kUnavailable, "run.status reply without a run object: " + status.dump()};
  return status["run"];
}

/// The units of one table run followed to their ends (the first one's progress line names the
/// others); one outcome line per unit, or {"runs": [...]}. 0 only if every unit is done + PASS.
int wait_for_runs(const Target& target, ControlClient& client,
                  const std::vector<db::history::RunId>& ids, bool json_out) {
  json runs = json::array();
  int code = kOk;
  for (const db::history::RunId id : ids) {
    json run;
    const int c = wait_for_run(target, client, id, json_out, &run);
    if (c == kStoppedFollowing) return c;
    if (c != kOk && code != kRunInterrupted) code = c;  // an interrupted unit says the most
    runs.push_back(run);
  }
  if (json_out)
    print_json(json{{"runs", runs}});
  else
    for (const json& run : runs) std::cout << station::control::outcome_line(run) << "\n";
  return code;
}

/// run start's units: --serial SN (repeatable: slots in order) or --slot SLOT=SN, not both.
json start_units(const RunArgs& a) {
  if (a.serials.empty() == a.slots.empty())
    throw Failure{kBadInput,
                  "run start: give the unit(s) with --serial SN (repeatable) or "
                  "--slot SLOT=SN (repeatable), not both"};
  json units = json::array();
  for (const std::string& sn : a.serials) {
    check_serial(sn);
    units.push_back({{"serial", sn}});
  }
  for (const std::string& spec : a.slots) {
    const auto eq = spec.find('=');
    if (eq == std::string::npos || eq == 0 || eq + 1 == spec.size())
      throw Failure{kBadInput, "--slot " + spec + ": expected SLOT=SERIAL (e.g. --slot B=SN-0042)"};
    check_serial(spec.substr(eq + 1));
    units.push_back({{"slot", spec.substr(0, eq)}, {"serial", spec.substr(eq + 1)}});
  }
  return units;
}

/// run.start's arguments: one unit as the request every daemon understands, several as "units".
json start_args(const RunArgs& a, const json& units) {
  json args = json::object();
  if (units.size() == 1 && !units[0].contains("slot"))
    args["serial"] = units[0]["serial"];  // one unit: the request every daemon understands
  else
    args["units"] = units;
  if (!a.sequence.empty()) args["sequence"] = a.sequence;
  if (!a.operator_name.empty()) args["operator"] = a.operator_name;
  return args;
}

}  // namespace

RunCommands add_run_commands(CLI::App& app, RunArgs& a) {
  RunCommands c{};
  auto* run = app.add_subcommand("run", "start, follow or abort a calibration run");
  run->require_subcommand(1);
  run->fallthrough();
  c.start = run->add_subcommand("start", "start a run of a unit (needs the control group)");
  c.start
      ->add_option("--serial", a.serials,
                   std::string("serial number: ") + db::history::kSerialRule +
                       "; repeat it for several units on the fixture (slots in the "
                       "configuration's order)")
      ->take_all();
  c.start->add_option("--slot", a.slots,
                      "SLOT=SERIAL: a unit in a named fixture slot (repeatable; instead of "
                      "--serial)");
  c.start->add_option("--sequence", a.sequence, "sequence name or file (default: the station's)");
  c.start->add_option("--operator", a.operator_name, "operator name (default: your user name)")
      ->check(text_check(station::control::kMaxNameChars));
  c.start->add_flag("--wait", a.wait, "follow the run to its end; exit 0 only for done + PASS");
  c.start
      ->add_option("--give-up-after", a.give_up_after_s,
                   "with --wait: seconds to wait for a daemon that stopped answering before "
                   "giving up (exit 4; default 600)")
      ->check(CLI::PositiveNumber);
  c.start->fallthrough();
  c.status = run->add_subcommand("status", "the daemon's state, or one run's (--run)");
  c.status->add_option("--run", a.run_id, "run id")->check(CLI::PositiveNumber);
  c.status->fallthrough();
  c.abort = run->add_subcommand("abort", "abort the active run (needs the control group)");
  c.abort->add_option("--reason", a.reason, "why (stored with the run)")
      ->check(text_check(station::control::kMaxReasonChars));
  c.abort->fallthrough();
  return c;
}

int cmd_run_start(const Target& t, const RunArgs& a, bool as_json) {
  g_outage_limit = std::chrono::duration<double>(a.give_up_after_s);
  const json args = start_args(a, start_units(a));
  ControlClient client = connect_or_fail(t);
  const json r = call(client, station::control::cmd::kRunStart, args);
  std::string what = "started: ";
  std::vector<db::history::RunId> ids;
  if (r.contains("units") && r["units"].is_array()) {
    for (const json& u : r["units"]) {
      what += (ids.empty() ? "" : ", ") + text(u, "serial") + " (slot " + text(u, "slot") +
              ", run " + text(u, "run_id") + ")";
      ids.push_back(u.at("run_id").get<db::history::RunId>());
    }
  } else {
    what += text(r, "serial");
    ids.push_back(r.at("run_id").get<db::history::RunId>());
  }
  if (a.wait && ids.size() > 1) {
    if (!as_json) std::cerr << "table run " << ids.front() << " " << what << "\n";
    return wait_for_runs(t, client, ids, as_json);
  }
  if (a.wait || as_json) return started(t, client, r, what, a.wait, as_json);
  std::cout << "run " << text(r, "run_id", "?") << " " << what << ", sequence "
            << text(r, "sequence", a.sequence)
            << (r.contains("steps") ? ", " + r["steps"].dump() + " steps" : "") << "\n";
  return kOk;
}

int cmd_run_status(const Target& t, const RunArgs& a, bool as_json) {
  json args = json::object();
  if (a.run_id > 0) args["run_id"] = a.run_id;
  return print_result(read_request(t, station::control::cmd::kRunStatus, args), as_json,
                      station::control::render_status_text);
}

int cmd_run_abort(const Target& t, const RunArgs& a, bool as_json) {
  json args = json::object();
  if (!a.reason.empty()) args["reason"] = a.reason;
  ControlClient client = connect_or_fail(t);
  const json r = call(client, station::control::cmd::kRunAbort, args);
  if (as_json)
    print_json(r);
  else if (r.contains("run") && r["run"].is_object())
    std::cout << station::control::outcome_line(r["run"]) << "\n";
  else
    std::cout << "abort requested"
              << (r.contains("run_id") ? " for run " + r["run_id"].dump() : std::string()) << "\n";
  return kOk;
}

int wait_for_run(const Target& target, ControlClient& client, db::history::RunId run_id,
                 bool json_out, json* outcome) {
  ProgressLine progress;
  json run;
  stop_following_on_signals();
  for (;;) {
    if (g_stop_following) {
      progress.end_line();
      std::cerr << "stationctl: stopped following run " << run_id
                << "; the run goes on (`stationctl run status --run " << run_id << "`)\n";
      return kStoppedFollowing;
    }
    std::optional<json> polled = poll_run(target, client, run_id, progress);
    if (!polled) continue;  // a signal stopped the following: said above
    run = std::move(*polled);
    if (is_terminal_state(text(run, "state"))) break;  // the outcome line below says it once
    progress.show(run);
    pause_unless_stopped(kPollPeriod);
  }
  progress.wipe();
  if (outcome)
    *outcome = run;
  else if (json_out)
    print_json(json{{"run", run}});
  else
    std::cout << station::control::outcome_line(run) << "\n";
  return exit_for_outcome(run);
}

int started(const Target& t, ControlClient& client, const json& r, const std::string& what,
            bool wait, bool as_json) {
  if (!wait) {
    if (as_json)
      print_json(r);
    else
      std::cout << "run " << text(r, "run_id", "?") << " " << what << "\n";
    return kOk;
  }
  if (!as_json) std::cerr << "run " << text(r, "run_id", "?") << " " << what << "\n";
  return wait_for_run(t, client, r.at("run_id").get<db::history::RunId>(), as_json);
}

}  // namespace imucal::tools::stationctl
