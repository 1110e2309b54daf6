#include "tools/stationweb/next_step.hpp"

#include <algorithm>

#include "tools/stationweb/html.hpp"

namespace imucal::tools::stationweb {

namespace {

using db::history::RunRecord;
using db::history::RunVerdict;

bool has_source(const RunRecord& r, const std::string& source) {
  return std::any_of(r.reasons.begin(), r.reasons.end(),
                     [&](const db::history::RunReason& x) { return x.source == source; });
}

std::string id_of(const RunRecord& r) { return std::to_string(r.run_id); }

bool is_field(const RunRecord& r) {
  return r.setting != calib::core::Setting::kFactory || !r.origin.empty();
}

/// A run the station, the daemon or its archive ended: its archive may still calibrate.
NextStep station_step(const RunRecord& r, std::optional<bool> complete) {
  const std::string id = id_of(r);
  const bool says_reprocess = r.failure_reason.find("reprocess it") != std::string::npos;
  if (r.archive_path.empty())
    return {"rerun", "",
            "No archive was kept: fix what ended it (the reason below), then run the "
            "unit again."};
  if (complete.value_or(false))
    return {"reprocess", "stationctl reprocess " + id,
            "The capture is complete: once the station is fixed, recalibrate it from its "
            "archive (a new run; no need to mount the unit again)."};
  if (says_reprocess)
    return {"reprocess", "stationctl reprocess " + id + " --partial",
            "The archive was recovered incomplete: reprocessing it gives a REVIEW at best (never "
            "the unit's active set); for an active set, run the unit again."};
  return {"rerun", "", "The capture did not complete: fix the station, then run the unit again."};
}

/// The step one REVIEW reason asks for.
NextStep review_step(const RunRecord& r, const std::string& source) {
  const std::string id = id_of(r);
  if (source == "field")
    return {"promote", "stationctl promote " + id + " --reason TEXT",
            "QA's decision: promote this field run to the unit's active parameters if its "
            "values are acceptable for the unit's use (its reason says what was not checked), "
            "or leave it as a record."};
  if (source == "partial archive")
    return {"rerun", "",
            "Calibrated from an incomplete archive: never the active set. Run the "
            "unit again for a complete capture."};
  if (source == "gap")
    return {"diagnose", "stationctl diagnose " + id,
            "The run departs from its model (the diagnosis below). Read the whole diagnosis; if "
            "the station signatures name this station (/signatures), fix it and reprocess the "
            "run; if the effect is the unit's, decide: re-mount and re-run, or reject the unit."};
  if (source == "cross-check")
    return {"remount", "",
            "The two methods disagree beyond the bound (the cross-check below): "
            "re-mount the unit and run it again; a mounting or table fault moves "
            "one method more than the other. The same disagreement twice: reject "
            "the unit or escalate."};
  if (source == "limits")
    return {"decide", "",
            "A parameter is outside the unit's limits: reject the unit, or run it "
            "once more if the mounting is in doubt."};
  return {"decide", "", "QA's decision: the reason below says what to judge."};
}

std::vector<NextStep> review_steps(const RunRecord& r) {
  // The order QA acts in: what the setting decides, what the data can still give, then why the
  // unit's figures are in doubt.
  static const char* const kOrder[] = {"field", "partial archive", "limits", "cross-check", "gap"};
  std::vector<NextStep> out;
  // A run stored without its reasons listed: a REVIEW cross-check is its reason.
  const bool crosscheck_only =
      r.reasons.empty() && r.crosscheck_verdict == db::history::Verdict::kReview;
  for (const char* source : kOrder)
    if (has_source(r, source) || (crosscheck_only && std::string(source) == "cross-check"))
      out.push_back(review_step(r, source));
  if (out.empty()) out.push_back(review_step(r, ""));
  return out;
}

/// An ABORTED run the daemon's stop ended: what happened, and what the kept archive can give.
NextStep daemon_stop_step(const RunRecord& r, std::optional<bool> complete) {
  const std::string what = "The station's daemon (stationd) was stopped during the run (\"" +
                           r.failure_reason +
                           "\"): neither an operator's abort nor the unit's failure. ";
  if (!r.archive_path.empty() && complete.value_or(false))
    return {"reprocess", "stationctl reprocess " + id_of(r),
            what +
                "The capture is complete: recalibrate it from its archive (a new run; no need "
                "to mount the unit again)."};
  if (!r.archive_path.empty())
    return {"rerun", "",
            what +
                "Its record does not say the capture completed: run the unit again. (Had it "
                "completed, `stationctl reprocess " +
                id_of(r) + "` would recalibrate the archive; it refuses an incomplete one.)"};
  return {"rerun", "", what + "No archive was kept: run the unit again."};
}

}  // namespace

std::vector<NextStep> next_steps(const RunRecord& r, const std::vector<RunRecord>& reprocesses,
                                 std::optional<bool> capture_complete,
                                 const std::optional<RunRecord>& newest) {
  if (!r.verdict)
    return {{"wait", "", "The run is still " + std::string(db::history::to_string(r.state)) + "."}};
  if (!reprocesses.empty()) {
    const RunRecord& n = reprocesses.front();
    const RunRecord& d = newest ? *newest : n;
    const std::string verdict = d.verdict ? db::history::to_string(*d.verdict) : "live";
    NextStep step{"see-reprocess", "",
                  d.run_id == n.run_id
                      ? "Reprocessed as run " + id_of(n) + " (" + verdict + "): run " + id_of(n) +
                            " decides; its page says what next."
                      : "Reprocessed as run " + id_of(n) + ", itself reprocessed as run " +
                            id_of(d) + " (" + verdict + ", the newest of the chain): run " +
                            id_of(d) + " decides; its page says what next."};
    step.decides = d.run_id;
    return {step};
  }
  switch (*r.verdict) {
    case RunVerdict::kPass:
      if (is_field(r) && !r.promoted_at_ms)
        return {{"promote", "stationctl promote " + id_of(r) + " --reason TEXT",
                 "A field or imported run is never active by itself: promote it if QA accepts "
                 "its values for the unit."}};
      return {{"none", "", "Nothing to do: PASS."}};
    case RunVerdict::kReview:
      return review_steps(r);
    case RunVerdict::kFailed:
      if (r.failure_reason.find("reprocess it") != std::string::npos)
        return {station_step(r, capture_complete)};
      return {{"rerun", "",
               "The unit's data or calibration failed: run it once more; failing "
               "again, reject the unit."}};
    case RunVerdict::kAborted:
      if (db::history::stopped_by_daemon(r)) return {daemon_stop_step(r, capture_complete)};
      return {{"rerun", "", "An operator aborted the run: run the unit again when ready."}};
    default:  // STATION-FAULT, INTERRUPTED: not the unit's
      return {station_step(r, capture_complete)};
  }
}

std::string next_step_section(const std::vector<NextStep>& steps) {
  if (steps.empty()) return "";
  const NextStep& p = steps.front();
  std::string s = "<div id='next-step' class='next' data-action='" + esc(p.action) +
                  "' data-command='" + esc(p.command) + "' data-decides='" +
                  (p.decides ? std::to_string(p.decides) : "") + "'>\n<p><b>Next step:</b> " +
                  (p.command.empty() ? "" : "<code>" + esc(p.command) + "</code> — ") +
                  esc(p.text) +
                  (p.decides ? " <a href='/run/" + std::to_string(p.decides) + "'>Go to run " +
                                   std::to_string(p.decides) + "</a>"
                             : "") +
                  "</p>\n";
  if (steps.size() > 1) {
    s += "<ul id='next-steps-more'>\n";
    for (std::size_t i = 1; i < steps.size(); ++i)
      s += "<li data-action='" + esc(steps[i].action) + "' data-command='" + esc(steps[i].command) +
           "'>" +
           (steps[i].command.empty() ? "" : "<code>" + esc(steps[i].command) + "</code> — ") +
           esc(steps[i].text) + "</li>\n";
    s += "</ul>\n";
  }
  return s + "</div>\n";
}

}  // namespace imucal::tools::stationweb
