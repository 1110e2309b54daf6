#include "tools/report/station_signatures.hpp"

#include <cmath>
#include <cstdio>
#include <map>
#include <mutex>
#include <set>
#include <stdexcept>

#include "calib/core/conventions.hpp"
#include "calib/core/site_presets.hpp"
#include "calib/sim/sim_input.hpp"
#include "sequences/library.hpp"

namespace imucal::tools::report {

namespace {

using nlohmann::json;

/// The sequence most runs followed.
std::string main_sequence(const std::vector<db::history::AinsResultRow>& rows) {
  std::map<std::string, int> n;
  for (const auto& r : rows) ++n[r.sequence_name];
  std::string best;
  for (const auto& [name, count] : n)
    if (best.empty() || count > n[best]) best = name;
  return best;
}

std::vector<calib::studies::fleet::StationError> measure_errors(const std::string& sequence) {
  sequences::MotionProfile profile;
  try {
    profile = sequences::load_profile(sequence);
  } catch (const std::exception& e) {
    throw db::history::InvalidInput(
        "station signatures: the runs' sequence \"" + sequence +
        "\" cannot be simulated for the station errors' responses: " + e.what());
  }
  std::vector<calib::studies::fleet::StationError> errors =
      calib::studies::fleet::station_error_catalogue();
  calib::studies::fleet::measure_responses(
      errors, calib::sim::truth_run_source(profile, calib::core::TableGeometry{},
                                           calib::core::demo_factory_site(),
                                           calib::effects::default_unit(), 100.0));
  return errors;
}

/// The responses of a sequence, measured once per process (a web view asks for them on every
/// page; they depend on the sequence alone).
std::vector<calib::studies::fleet::StationError> measured_errors(
    const std::string& sequence, const std::function<void(const std::string&)>& progress) {
  static std::mutex mutex;
  static std::map<std::string, std::vector<calib::studies::fleet::StationError>> cache;
  std::lock_guard<std::mutex> lock(mutex);
  const auto it = cache.find(sequence);
  if (it != cache.end()) return it->second;
  if (progress) progress("measuring the station errors' responses on " + sequence);
  return cache[sequence] = measure_errors(sequence);
}

json fit_json(const calib::studies::fleet::StationFit& f,
              const calib::studies::fleet::StationError& e) {
  json j = {{"effect", f.effect},
            {"term", e.term},
            {"size_si", f.size_si},
            {"sigma_si", f.sigma_si},
            {"z", f.z()},
            {"unit", e.unit},
            {"size", f.size_si * e.si_to_human},
            {"sigma", f.sigma_si * e.si_to_human}};
  if (!e.alt_unit.empty())
    j["also"] = {{"unit", e.alt_unit},
                 {"size", f.size_si * e.si_to_alt},
                 {"sigma", f.sigma_si * e.si_to_alt}};
  return j;
}

/// "common accelerometer scale +52 ± 6 ppm against the fleet: check the surveyed gravity of this
/// site" (the size in its second unit where it has one: what moved).
std::string cause_text(const json& fit, const calib::studies::fleet::StationError& e) {
  const json& shown = fit.contains("also") ? fit["also"] : fit;
  char buf[160];
  std::snprintf(buf, sizeof buf, "%s %+.3g ± %.2g %s", e.term.c_str(), shown["size"].get<double>(),
                shown["sigma"].get<double>(), shown["unit"].get<std::string>().c_str());
  std::string s = buf;
  if (fit.contains("also")) {
    std::snprintf(buf, sizeof buf, " (%s %+.3g %s)", e.effect.c_str(), fit["size"].get<double>(),
                  fit["unit"].get<std::string>().c_str());
    s += buf;
  }
  return s + " against the fleet: " + e.advice;
}

/// What QA does with a flagged station's runs once the causes are fixed. A wrong surveyed gravity
/// is a station setting, so reprocessing the archives with the re-surveyed value corrects every
/// run (stationctl reprocess takes the station's own run ids, several at once); a table or fixture
/// fault is in the recorded data, so no setting corrects it: the units are calibrated again after
/// the service.
json remedy(const std::vector<calib::studies::fleet::StationFit>& alarms,
            const std::string& station, const json& local_ids) {
  const std::string recalibrate =
      "once the station is serviced, calibrate the units again (the fault is in these runs' "
      "data: no setting corrects it)";
  const calib::studies::fleet::StationFit* gravity = nullptr;
  for (const calib::studies::fleet::StationFit& a : alarms)
    if (a.effect == "gravity_error") gravity = &a;
  if (!gravity) return {{"reprocess", false}, {"text", recalibrate}};
  std::string command = "stationctl reprocess";
  for (const json& id : local_ids) command += " " + std::to_string(id.get<long long>());
  command += " --gravity-mps2 G";
  char fit[96];
  std::snprintf(fit, sizeof fit, "%+.2g m/s² (%+.3g µg)", gravity->size_si,
                gravity->size_si / kMicroG_mps2);
  std::string text = "once the site's gravity is re-surveyed (the fleet puts it " +
                     std::string(fit) + " from the configured value), reprocess the runs at " +
                     station + " with G the new survey, and promote the new results: " + command +
                     " (earlier periods' runs too, if it was wrong then: --trend shows since when)";
  if (alarms.size() > 1) text += "; for the other fault, " + recalibrate;
  return {{"reprocess", true}, {"command", command}, {"text", text}};
}

const calib::studies::fleet::StationError& error_named(
    const std::vector<calib::studies::fleet::StationError>& errors, const std::string& effect) {
  for (const calib::studies::fleet::StationError& e : errors)
    if (e.effect == effect) return e;
  throw std::logic_error("station error " + effect + " is not in the catalogue");
}

/// A named error as JSON: its fit and the cause QA reads.
json alarm_json(const calib::studies::fleet::StationFit& fit,
                const std::vector<calib::studies::fleet::StationError>& errors) {
  const calib::studies::fleet::StationError& e = error_named(errors, fit.effect);
  json j = fit_json(fit, e);
  j["cause"] = cause_text(j, e);
  return j;
}

}  // namespace

db::history::FleetFilter signature_window(const db::history::Repository& history,
                                          const std::string& since, const std::string& until,
                                          int default_days) {
  constexpr db::history::TimestampMs kDayMs = 86400000;
  db::history::FleetFilter f;
  auto parse = [](const std::string& field, const std::string& text) {
    try {
      return db::history::parse_time_utc(text);
    } catch (const db::history::InvalidInput& e) {
      throw WindowError(field, e.what());
    }
  };
  if (!until.empty()) f.until_ms = parse("until", until) + (until.size() == 10 ? kDayMs : 0);
  if (!since.empty()) f.since_ms = parse("since", since);
  if (!f.until_ms) {
    const auto newest = history.recent_runs(1);
    if (newest.empty()) return f;
    f.until_ms = (db::history::utc_day(newest.front().started_at_ms) + 1) * kDayMs;
  }
  if (!f.since_ms) f.since_ms = *f.until_ms - default_days * kDayMs;
  if (*f.since_ms >= *f.until_ms)
    throw WindowError("until", "the window from " + db::history::format_time_utc(*f.since_ms) +
                                   " until (before) " + db::history::format_time_utc(*f.until_ms) +
                                   " holds no time: since must be earlier than until");
  return f;
}

namespace {
/// The report of one period's rows (station_signature_report's, without the read).
json report_of_rows(const std::vector<db::history::AinsResultRow>& rows,
                    const calib::studies::fleet::SignatureOptions& options,
                    const std::function<void(const std::string&)>& progress);
}  // namespace

json station_signature_report(const db::history::FleetStats& stats,
                              const db::history::FleetFilter& window,
                              const calib::studies::fleet::SignatureOptions& options,
                              const std::function<void(const std::string&)>& progress) {
  json report = report_of_rows(stats.ains_results(window), options, progress);
  // Issue #50: the station's own faults in the window (table, CAN bus, disk) beside its
  // signature; they are never among the units' results the signature is computed from.
  std::map<std::string, std::int64_t> faults;
  for (const auto& v : stats.verdict_counts_per_station(window))
    faults[v.station] = v.station_fault;
  for (json& st : report["stations"]) {
    const auto it = faults.find(st["station"].get<std::string>());
    st["station_faults"] = it == faults.end() ? 0 : it->second;
  }
  return report;
}

namespace {

json report_of_rows(const std::vector<db::history::AinsResultRow>& rows,
                    const calib::studies::fleet::SignatureOptions& options,
                    const std::function<void(const std::string&)>& progress) {
  json report = {{"runs", rows.size()}, {"false_alarm", options.false_alarm}};
  if (rows.empty()) {
    report["stations"] = json::array();
    return report;
  }
  const std::string sequence = main_sequence(rows);
  const std::vector<calib::studies::fleet::StationError> errors =
      measured_errors(sequence, progress);
  std::vector<calib::studies::fleet::SignatureRun> runs;
  std::map<std::int64_t, std::int64_t> local_id;         // the history's id -> the station's own
  std::map<std::string, std::set<std::string>> serials;  // the units each station ran
  // A station error moves a run's parameters by the response of the run's own sequence: runs of
  // another sequence are left out and counted (issue #52), not fitted with these responses.
  std::map<std::string, int> other_sequences;
  for (const auto& r : rows) {
    if (r.sequence_name != sequence) {
      ++other_sequences[r.sequence_name];
      continue;
    }
    runs.push_back({r.station, r.serial, r.run_id, r.value.to_vector(), r.sigma.to_vector()});
    local_id[r.run_id] = r.local_run_id;
    serials[r.station].insert(r.serial);
  }
  const calib::studies::fleet::FleetSignatures fs =
      calib::studies::fleet::station_signatures(runs, errors, options);
  report["runs"] = runs.size();
  report["sequence"] = sequence;
  json left_out = json::array();
  for (const auto& [name, count] : other_sequences)
    left_out.push_back({{"sequence", name}, {"runs", count}});
  report["other_sequences"] = left_out;
  report["z_threshold"] = fs.z_threshold;
  json stations = json::array();
  for (const calib::studies::fleet::StationSignature& sig : fs.stations) {
    json s = {{"station", sig.station},
              {"runs", sig.runs},
              // Every unit it ran (issue #52 item 3); population_units counts only those its
              // population evidence used (none when no other station is a reference).
              {"units", serials[sig.station].size()},
              {"population_units", sig.population_units},
              {"repeat_units", sig.repeat_units},
              {"assessed", sig.assessed}};
    if (!sig.assessed) s["why_not"] = sig.why_not;
    json fits = json::array();
    for (std::size_t k = 0; k < sig.fits.size(); ++k)
      fits.push_back(fit_json(sig.fits[k], errors[k]));
    s["fits"] = fits;
    s["flagged"] = sig.alarm.has_value();
    if (sig.alarm) {
      json alarms = json::array(), others = json::array();
      for (const calib::studies::fleet::StationFit& f : sig.alarms)
        alarms.push_back(alarm_json(f, errors));
      for (const calib::studies::fleet::StationFit& f : sig.fits_given_alarms)
        others.push_back(fit_json(f, error_named(errors, f.effect)));
      s["alarm"] = alarms.front();
      s["alarms"] = alarms;
      s["fits_given_alarms"] = others;
      s["run_ids"] = sig.run_ids;
      json local = json::array();
      for (const std::int64_t id : sig.run_ids) local.push_back(local_id.at(id));
      s["local_run_ids"] = local;
      s["remedy"] = remedy(sig.alarms, sig.station, local);
    }
    stations.push_back(s);
  }
  report["stations"] = stations;
  return report;
}

}  // namespace

std::string render_signatures_text(const json& report) {
  if (report["stations"].empty()) return "no factory AINS results in this window\n";
  char buf[256];
  std::snprintf(buf, sizeof buf,
                "%d runs, responses on %s; flagged at |z| >= %.2f (false alarms %.3g per station "
                "and period)\n",
                report["runs"].get<int>(), report["sequence"].get<std::string>().c_str(),
                report["z_threshold"].get<double>(), report["false_alarm"].get<double>());
  std::string out = buf;
  if (report.contains("other_sequences"))
    for (const json& o : report["other_sequences"])
      out += "left out: " + std::to_string(o["runs"].get<int>()) + " run(s) of " +
             o["sequence"].get<std::string>() + " (the responses are " +
             report["sequence"].get<std::string>() + "'s)\n";
  for (const json& s : report["stations"]) {
    std::snprintf(buf, sizeof buf, "%-16s %4d runs, %3d units, %2d seen elsewhere",
                  s["station"].get<std::string>().c_str(), s["runs"].get<int>(),
                  s["units"].get<int>(), s["repeat_units"].get<int>());
    out += buf;
    if (s.contains("station_faults"))
      out += ", " + std::to_string(s["station_faults"].get<std::int64_t>()) + " station fault(s)";
    if (!s["assessed"].get<bool>()) {
      out += "  not assessed: " + s["why_not"].get<std::string>() + "\n";
      continue;
    }
    const bool flagged = s["flagged"].get<bool>();
    // A flagged station's other candidates are shown given its named errors (each alone, they
    // would echo the named error's size through their overlapping responses).
    for (const json& f : flagged ? s["fits_given_alarms"] : s["fits"]) {
      std::snprintf(buf, sizeof buf, "  %s z %+.1f", f["effect"].get<std::string>().c_str(),
                    f["z"].get<double>());
      out += buf;
    }
    if (!flagged) {
      out += "  ok\n";
      continue;
    }
    const auto& ids = s["run_ids"];
    out += "  FLAGGED (the others' z given the errors named)\n";
    for (const json& alarm : s["alarms"]) out += "    " + alarm["cause"].get<std::string>() + "\n";
    out += "    runs it touches (" + std::to_string(ids.size()) + "):";
    for (const json& id : ids) out += " " + std::to_string(id.get<long long>());
    if (s["local_run_ids"] != ids) {
      out += "\n    (the station's own ids:";
      for (const json& id : s["local_run_ids"]) out += " " + std::to_string(id.get<long long>());
      out += ")";
    }
    out += "\n    " + s["remedy"]["text"].get<std::string>() + "\n";
  }
  return out;
}

namespace {

/// One station of one period, condensed: its strongest fit and, when flagged, the cause.
json trend_cell(const json& st) {
  json cell = {{"station", st["station"]},
               {"assessed", st["assessed"]},
               {"flagged", st.value("flagged", false)}};
  const json* strongest = nullptr;
  for (const json& f : st["fits"])
    if (!strongest || std::abs(f["z"].get<double>()) > std::abs((*strongest)["z"].get<double>()))
      strongest = &f;
  if (strongest)
    cell["strongest"] = {{"effect", (*strongest)["effect"]},
                         {"z", (*strongest)["z"]},
                         {"size", (*strongest)["size"]},
                         {"sigma", (*strongest)["sigma"]},
                         {"unit", (*strongest)["unit"]}};
  if (cell["flagged"].get<bool>()) {
    cell["alarm"] = st["alarm"];
    std::string causes;
    for (const json& alarm : st["alarms"])
      causes += (causes.empty() ? "" : "; ") + alarm["cause"].get<std::string>();
    cell["cause"] = causes;
  }
  return cell;
}

}  // namespace

json station_signature_trend(const db::history::FleetStats& stats,
                             const db::history::FleetFilter& window, int period_days,
                             const calib::studies::fleet::SignatureOptions& options,
                             const std::function<void(const std::string&)>& progress) {
  constexpr db::history::TimestampMs kDayMs = 86400000;
  if (period_days < 1 || period_days > 366)
    throw db::history::InvalidInput("period_days: " + std::to_string(period_days) +
                                    " is not a period of 1 to 366 days");
  json trend = {{"period_days", period_days},
                {"false_alarm", options.false_alarm},
                {"periods", json::array()}};
  if (!window.since_ms || !window.until_ms) {
    trend["stations"] = json::array();
    return trend;
  }
  const db::history::TimestampMs period_ms = period_days * kDayMs;
  const db::history::TimestampMs span = *window.until_ms - *window.since_ms;
  const db::history::TimestampMs n =
      std::max<db::history::TimestampMs>(1, (span + period_ms - 1) / period_ms);
  std::set<std::string> names;
  // One read for the whole window, cut into periods here (twelve reads cost twelve queries).
  db::history::FleetFilter all = window;
  all.since_ms = *window.until_ms - n * period_ms;
  const std::vector<db::history::AinsResultRow> rows = stats.ains_results(all);
  for (db::history::TimestampMs k = 0; k < n; ++k) {
    db::history::FleetFilter f = window;
    f.since_ms = *window.until_ms - (n - k) * period_ms;
    f.until_ms = *f.since_ms + period_ms;
    if (progress)
      progress("period " + std::to_string(k + 1) + " of " + std::to_string(n) + " (from " +
               db::history::format_time_utc(*f.since_ms) + ")");
    std::vector<db::history::AinsResultRow> in_period;
    for (const db::history::AinsResultRow& r : rows)
      if (r.started_at_ms >= *f.since_ms && r.started_at_ms < *f.until_ms) in_period.push_back(r);
    const json r = report_of_rows(in_period, options, {});
    json period = {{"since_ms", *f.since_ms},
                   {"until_ms", *f.until_ms},
                   {"runs", r["runs"]},
                   {"stations", json::array()}};
    if (r.contains("z_threshold")) trend["z_threshold"] = r["z_threshold"];
    for (const json& st : r["stations"]) {
      period["stations"].push_back(trend_cell(st));
      names.insert(st["station"].get<std::string>());
    }
    trend["periods"].push_back(period);
  }
  trend["stations"] = std::vector<std::string>(names.begin(), names.end());
  return trend;
}

const json* signature_trend_cell(const json& period, const std::string& station) {
  for (const json& c : period["stations"])
    if (c["station"] == station) return &c;
  return nullptr;
}

std::string render_signature_trend_text(const json& trend) {
  if (trend["stations"].empty()) return "no factory AINS results in this window\n";
  char buf[256];
  std::string out;
  if (trend.contains("z_threshold")) {
    std::snprintf(buf, sizeof buf,
                  "strongest |z| of each station per %d-day period ('*' flagged at |z| >= %.2f, "
                  "false alarms %.3g per station and period; '-' no assessment)\n",
                  trend["period_days"].get<int>(), trend["z_threshold"].get<double>(),
                  trend["false_alarm"].get<double>());
    out += buf;
  }
  std::snprintf(buf, sizeof buf, "%-16s", "period from");
  out += buf;
  for (const json& p : trend["periods"])
    out +=
        " " +
        db::history::format_time_utc(p["since_ms"].get<db::history::TimestampMs>()).substr(5, 5) +
        " ";
  out += "\n";
  std::map<std::string, std::string> causes;  // station -> its flagged periods' lines
  for (const json& name : trend["stations"]) {
    std::snprintf(buf, sizeof buf, "%-16s", name.get<std::string>().c_str());
    out += buf;
    for (const json& p : trend["periods"]) {
      const json* cell = signature_trend_cell(p, name.get<std::string>());
      if (!cell || !cell->contains("strongest")) {
        out += "     -  ";
        continue;
      }
      const bool flagged = (*cell)["flagged"].get<bool>();
      std::snprintf(buf, sizeof buf, " %5.1f%s ", std::abs((*cell)["strongest"]["z"].get<double>()),
                    flagged ? "*" : " ");
      out += buf;
      if (flagged)
        causes[name.get<std::string>()] +=
            "    " +
            db::history::format_time_utc(p["since_ms"].get<db::history::TimestampMs>())
                .substr(0, 10) +
            ": " + (*cell)["cause"].get<std::string>() + "\n";
    }
    out += "\n";
  }
  for (const auto& [name, lines] : causes) out += name + " flagged:\n" + lines;
  return out;
}

}  // namespace imucal::tools::report
