// "/runs": the runs behind an aggregate (issue #52 item 8) — a fleet bar (station, day), a verdict
// count (station, verdict, window), a distribution (station, param, window) — with the fleet
// page's filters, read by the same parser (list_filter.hpp), listed with `stationctl history`'s
// columns (run_table) and, for a parameter, its AINS value. ?format=csv|json gives the list as
// data.
//
//   station, serial, setting, verdict, since, until   as on /fleet (list_filter.hpp), except:
//                     setting absent is every setting; without since, until and serial, the 30
//                     days up to the newest run's day; with a serial and no date, every time
//   capture           newest (default): one capture once, as the fleet counts — a run a later
//                     reprocess of the same archive replaced (db::history::superseded_runs) is
//                     listed apart, not counted; every: every run counted
//   param             a parameter-set name: only runs with an AINS value of it, the value shown;
//                     a frame-dependent one (db::history::frame_dependent) only in the housing
//                     frame, as the fleet's distribution (the others counted apart)
//   limit             1..2000 rows shown (default 500), newest first; the count says how many match
#include <algorithm>
#include <cctype>
#include <map>
#include <set>
#include <unordered_set>

#include "calib/core/calibration_input.hpp"
#include "calib/core/param_set.hpp"
#include "db/history/fleet_stats.hpp"
#include "tools/stationweb/html.hpp"
#include "tools/stationweb/list_filter.hpp"
#include "tools/stationweb/page_util.hpp"
#include "tools/stationweb/pages.hpp"
#include "tools/stationweb/run_table.hpp"

namespace imucal::tools::stationweb {

namespace {

constexpr std::size_t kRunsDefaultLimit = 500, kRunsMaxLimit = 2000;

struct RunsQuery {
  ListFilter list;
  int param = -1;  ///< parameter index, -1: none
  std::size_t limit = kRunsDefaultLimit;
  bool every_capture = false;  ///< capture=every: superseded runs counted too
};

RunsQuery parse_runs_query(const History& history, const Params& query) {
  RunsQuery q;
  const bool serial_given = !trimmed(query_value(query, "serial")).empty();
  q.list = parse_list_filter(history, query, std::nullopt, !serial_given);
  if (const std::string param = trimmed(query_value(query, "param")); !param.empty()) {
    try {
      q.param = db::history::param_index(param);
    } catch (const db::history::InvalidInput& e) {
      bad_input("param", e.what());
    }
  }
  const std::string capture = trimmed(query_value(query, "capture"));
  if (capture == "every")
    q.every_capture = true;
  else if (!capture.empty() && capture != "newest")
    bad_input("capture", "\"" + capture.substr(0, 40) +
                             "\" is not newest (one capture once, as /fleet counts) or every");
  const std::string limit = query_value(query, "limit");
  if (!limit.empty()) {
    bool digits = limit.size() <= 5;
    for (char c : limit) digits = digits && std::isdigit(static_cast<unsigned char>(c));
    q.limit = digits ? std::stoul(limit) : 0;
    if (q.limit < 1 || q.limit > kRunsMaxLimit)
      bad_input("limit", "\"" + limit.substr(0, 40) + "\" is not a whole number from 1 to " +
                             std::to_string(kRunsMaxLimit));
  }
  return q;
}

struct Listed {
  std::vector<db::history::RunRecord> runs;  ///< newest first, at most limit
  std::vector<double> value_si;              ///< the parameter's AINS value per listed run
  std::size_t matched = 0;                   ///< every run the filters take and the rule counts
  /// The runs the filters take that the capture rule does not count (a later reprocess stands
  /// for them), newest first; and a frame-dependent parameter's results in another frame.
  std::vector<db::history::RunRecord> superseded, other_frame;
};

struct PastUntil {};  ///< ends the time-ordered export once it passes the window

bool verdict_taken(const db::history::FleetFilter& f, const db::history::RunRecord& r) {
  if (!f.verdict) return true;
  return listed(db::history::verdict_list(*f.verdict),
                r.verdict ? db::history::to_string(*r.verdict) : std::string("live"));
}

void newest_first(std::vector<db::history::RunRecord>& runs) {
  std::stable_sort(runs.begin(), runs.end(), [](const auto& a, const auto& b) {
    return a.started_at_ms > b.started_at_ms ||
           (a.started_at_ms == b.started_at_ms && a.run_id > b.run_id);
  });
}

Listed list_runs(const History& history, const RunsQuery& q) {
  const db::history::FleetFilter& f = q.list.filter;
  std::unordered_set<db::history::RunId> superseded;
  if (!q.every_capture)
    for (const auto id : db::history::superseded_runs(history.stats->reprocess_links()))
      superseded.insert(id);
  const bool by_frame = q.param >= 0 && db::history::frame_dependent(q.param);
  db::history::ExportFilter export_filter;
  export_filter.serial = f.serial;
  export_filter.since_ms = f.since_ms;
  export_filter.station = f.station;
  std::vector<std::pair<db::history::RunRecord, double>> all;
  Listed out;
  std::set<db::history::RunId> seen;
  try {
    history.repo->export_rows(export_filter, [&](const db::history::ExportRow& row) {
      const db::history::RunRecord& r = row.run;
      if (f.until_ms && r.started_at_ms >= *f.until_ms) {
        if (f.since_ms) throw PastUntil{};  // ordered by time: nothing later matches
        return;
      }
      if (!verdict_taken(f, r)) return;
      if (f.setting && calib::core::setting_name(r.setting) != *f.setting) return;
      double value = 0.0;
      if (q.param >= 0) {
        const auto& c = row.calibration;
        if (!c || c->method != db::history::Method::kAins) return;
        if (listed(c->unobservable, calib::core::param_info(q.param).name)) return;
        value = c->params.to_vector()(q.param);
        if (by_frame && c->body_frame != calib::core::BodyFrame::kHousing) {
          if (seen.insert(r.run_id).second && !superseded.count(r.run_id))
            out.other_frame.push_back(r);
          return;
        }
      }
      if (!seen.insert(r.run_id).second) return;
      if (superseded.count(r.run_id))
        out.superseded.push_back(r);
      else
        all.push_back({r, value});
    });
  } catch (const PastUntil&) {
  }
  std::stable_sort(all.begin(), all.end(), [](const auto& a, const auto& b) {
    return a.first.started_at_ms > b.first.started_at_ms ||
           (a.first.started_at_ms == b.first.started_at_ms && a.first.run_id > b.first.run_id);
  });
  newest_first(out.superseded);
  newest_first(out.other_frame);
  out.matched = all.size();
  for (std::size_t i = 0; i < all.size() && i < q.limit; ++i) {
    out.runs.push_back(all[i].first);
    out.value_si.push_back(all[i].second);
  }
  return out;
}

/// The filters as a sentence, each value as given, and the window as read (clamped dates noted).
std::string filters_line(const RunsQuery& q, const Params& query) {
  std::string s;
  for (const char* name : {"station", "serial", "verdict", "setting", "param"}) {
    const std::string v = trimmed(query_value(query, name));
    if (!v.empty()) s += std::string(s.empty() ? "" : ", ") + name + " " + esc(v);
  }
  s += std::string(s.empty() ? "" : ", ") + "runs started " + window_text(q.list.filter);
  if (q.list.default_window)
    s += " (the default window: " + std::to_string(kDefaultWindowDays) +
         " days up to the newest run's day)";
  if (!q.list.notes.empty())
    s += " <span id='window-note' class='REVIEW'>" + esc(q.list.notes) + "</span>";
  return s;
}

/// What the count counts (issue #52, the audit's F1): the fleet's rule, said on the page.
std::string rule_line(const RunsQuery& q, const Listed& l, const std::string& every_href) {
  std::string s = "<p id='capture-rule' data-capture='" +
                  std::string(q.every_capture ? "every" : "newest") + "' data-superseded='" +
                  std::to_string(l.superseded.size()) + "'>";
  if (q.every_capture)
    return s +
           "Every run counted, a capture's reprocesses too (capture=every); the fleet page "
           "counts one capture once.</p>\n";
  s += "Counted as the fleet page counts: one capture once — a run and its reprocesses (the same "
       "archive calibrated again) are one capture, stood for by its newest run.";
  if (!l.superseded.empty())
    s += " " + count_of(static_cast<std::int64_t>(l.superseded.size()), "run") +
         " the filters take " + (l.superseded.size() == 1 ? "is" : "are") +
         " not counted: a later reprocess replaced " + (l.superseded.size() == 1 ? "it" : "them") +
         " (<a href='#runs-superseded'>listed apart below</a>; <a href='" + esc(every_href) +
         "'>every run</a>).";
  return s + "</p>\n";
}

}  // namespace

Reply runs_reply(const History& history, const Params& query) {
  check_known_params(query, {"station", "serial", "verdict", "setting", "since", "until", "param",
                             "capture", "limit", "format"});
  const Format format = parse_format(query);
  const RunsQuery q = parse_runs_query(history, query);
  const Listed l = list_runs(history, q);
  std::string header;
  std::vector<std::string> cells, values;
  if (q.param >= 0) {
    const calib::core::ParamInfo& info = calib::core::param_info(q.param);
    header = info.name + " [" + info.human_unit + "]";
    for (double v : l.value_si) {
      cells.push_back("<span data-value-si='" + exact(v) + "'>" +
                      fmt("%.6g", v * info.si_to_human) + "</span>");
      values.push_back(fmt("%.17g", v * info.si_to_human));
    }
  }
  if (format == Format::kJson)
    return {run_list_json("", l.runs, l.matched), "application/json", "runs.json"};
  if (format == Format::kCsv)
    return {run_list_csv(l.runs, header, values), "text/csv; charset=utf-8", "runs.csv"};
  // The page's own URL without format (no stray "&": issue #52 F12), and with capture=every.
  std::string target = "/runs", every = "/runs";
  for (const auto& [k, v] : query) {
    if (k == "format" || v.empty()) continue;
    target += (target.size() == 5 ? "?" : "&") + k + "=" + url_encode(v);
    if (k != "capture") every += (every.size() == 5 ? "?" : "&") + k + "=" + url_encode(v);
  }
  every += std::string(every.size() == 5 ? "?" : "&") + "capture=every";
  std::string b = "<h1>Runs</h1>\n<p id='runs-filters'>" + filters_line(q, query) + "</p>\n";
  b += rule_line(q, l, every);
  b += "<p><span id='runs-matched' data-value='" + std::to_string(l.matched) + "'>" +
       std::to_string(l.matched) + "</span> run" + (l.matched == 1 ? "" : "s") + " match" +
       (l.matched == 1 ? "es" : "") +
       (l.matched > l.runs.size() ? "; the newest " + std::to_string(l.runs.size()) +
                                        " shown (limit=" + std::to_string(q.limit) + ")"
                                  : "") +
       ".</p>\n";
  if (!l.other_frame.empty())
    b += "<p id='runs-other-frame' data-value='" + std::to_string(l.other_frame.size()) + "'>" +
         count_of(static_cast<std::int64_t>(l.other_frame.size()), "run") +
         " with a value not counted: " + calib::core::param_info(q.param).name +
         " depends on the body frame, and " + (l.other_frame.size() == 1 ? "its" : "their") +
         " result is in the accelerometer-symmetric frame (a field run), not the housing frame "
         "the fleet's distribution counts (listed apart below).</p>\n";
  b += request_form("/runs", query, "Filters (the same as the fleet pages'):");
  if (l.runs.empty())
    b += "<p>No run matches.</p>\n";
  else
    b += run_table(history, l.runs, true, "runs", esc(header), cells) + download_links(target);
  if (!l.superseded.empty())
    b += "<h2>Not counted: replaced by a later reprocess</h2>\n" +
         run_table(history, l.superseded, true, "runs-superseded");
  if (!l.other_frame.empty())
    b += "<h2>Not counted: another body frame</h2>\n" +
         run_table(history, l.other_frame, true, "runs-other-frame-list");
  return {page("Runs", b)};
}

}  // namespace imucal::tools::stationweb
