// "/compare?a=N&b=M[&method=ains|nlsq|legacy][&format=csv|json]": two runs side by side (issue #52
// item 8) — each parameter's value ± 1σ of run A and of run B (the same method's), their
// difference B − A, its σ (both runs' 1σ combined, sqrt(σA² + σB²): two calibrations are
// independent estimates) and the difference in those σ. A parameter either run does not determine
// is "not compared". The numbers in SI and full precision in data attributes, CSV and JSON.
#include <cctype>
#include <cmath>

#include "calib/core/param_set.hpp"
#include "station/control/record_json.hpp"
#include "tools/stationweb/html.hpp"
#include "tools/stationweb/page_util.hpp"
#include "tools/stationweb/pages.hpp"
#include "tools/stationweb/run_page_parts.hpp"
#include "tools/stationweb/run_table.hpp"

namespace imucal::tools::stationweb {

namespace {

struct Side {
  db::history::RunDetails details;
  std::size_t index = 0;  ///< of the compared method's calibration in details.calibrations
  const db::history::CalibrationRecord* operator->() const { return &details.calibrations[index]; }
};

struct Row {
  const calib::core::ParamInfo* info;
  bool compared = false;
  double a = 0, sa = 0, b = 0, sb = 0, diff = 0, sigma = 0, z = 0;  ///< SI; z: diff / sigma
};

db::history::RunId run_id_field(const std::string& field, const std::string& text) {
  bool digits = !text.empty() && text.size() <= 18;
  for (char c : text) digits = digits && std::isdigit(static_cast<unsigned char>(c));
  const db::history::RunId id = digits ? std::stoll(text) : 0;
  if (id < 1) bad_input(field, "\"" + text.substr(0, 40) + "\" is not a run number (>= 1)");
  return id;
}

db::history::Method method_field(const std::string& text) {
  if (text.empty() || text == "ains") return db::history::Method::kAins;
  if (text == "nlsq") return db::history::Method::kNlsq;
  if (text == "legacy") return db::history::Method::kLegacy;
  bad_input("method", "\"" + text.substr(0, 40) + "\" is not a method: ains, nlsq or legacy");
}

Side side(const History& history, const std::string& field, db::history::RunId id,
          db::history::Method method) {
  Side s;
  try {
    s.details = history.repo->show(id);
  } catch (const db::history::NotFound&) {
    throw PageError(404, field, field + ": no run " + std::to_string(id) + " in this history");
  }
  s.index = s.details.calibrations.size();
  for (std::size_t i = 0; i < s.details.calibrations.size(); ++i)
    if (s.details.calibrations[i].method == method) s.index = i;
  if (s.index == s.details.calibrations.size())
    bad_input(field, "run " + std::to_string(id) + " has no " + db::history::to_string(method) +
                         " calibration (a " +
                         (s.details.run.verdict ? db::history::to_string(*s.details.run.verdict)
                                                : "live") +
                         " run); choose another run or method");
  return s;
}

std::vector<Row> compare_rows(const Side& a, const Side& b) {
  const calib::core::ParamVector va = a->params.to_vector(), sa = a->sigma.to_vector();
  const calib::core::ParamVector vb = b->params.to_vector(), sb = b->sigma.to_vector();
  std::vector<Row> rows;
  for (int i = 0; i < calib::core::ParamSet::kSize; ++i) {
    Row r{&calib::core::param_info(i)};
    r.compared = !listed(a->unobservable, r.info->name) && !listed(b->unobservable, r.info->name);
    r.a = va(i), r.sa = sa(i), r.b = vb(i), r.sb = sb(i);
    r.diff = r.b - r.a;
    r.sigma = std::hypot(r.sa, r.sb);
    r.z = r.sigma > 0 ? r.diff / r.sigma : NAN;
    rows.push_back(r);
  }
  return rows;
}

std::string compare_json(const Side& a, const Side& b, const std::vector<Row>& rows,
                         db::history::Method m) {
  nlohmann::json j = {{"method", db::history::to_string(m)},
                      {"a", station::control::run_record_json(a.details.run)},
                      {"b", station::control::run_record_json(b.details.run)},
                      {"parameters", nlohmann::json::array()}};
  auto num = [](double v) {
    return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr);
  };
  for (const Row& r : rows)
    j["parameters"].push_back({{"name", r.info->name},
                               {"compared", r.compared},
                               {"a_si", r.a},
                               {"a_sigma_si", r.sa},
                               {"b_si", r.b},
                               {"b_sigma_si", r.sb},
                               {"diff_si", r.diff},
                               {"sigma_si", r.sigma},
                               {"diff_in_sigma", num(r.z)},
                               {"human_unit", r.info->human_unit},
                               {"si_to_human", r.info->si_to_human}});
  return j.dump(2) + "\n";
}

std::string compare_csv(const std::vector<Row>& rows) {
  std::string s =
      "parameter,human_unit,compared,a_si,a_sigma_si,b_si,b_sigma_si,diff_si,"
      "sigma_si,diff_in_sigma\n";
  for (const Row& r : rows)
    s += r.info->name + "," + csv_field(r.info->human_unit) + "," + (r.compared ? "yes" : "no") +
         "," + exact(r.a) + "," + exact(r.sa) + "," + exact(r.b) + "," + exact(r.sb) + "," +
         exact(r.diff) + "," + exact(r.sigma) + "," + (std::isfinite(r.z) ? exact(r.z) : "") + "\n";
  return s;
}

std::string row_html(const Row& r) {
  const double h = r.info->si_to_human;
  std::string s = "<tr data-param='" + r.info->name + "' data-compared='" +
                  (r.compared ? "yes" : "no") + "' data-a-si='" + exact(r.a) + "' data-b-si='" +
                  exact(r.b) + "' data-diff-si='" + exact(r.diff) + "' data-sigma-si='" +
                  exact(r.sigma) + "' data-z='" + (std::isfinite(r.z) ? exact(r.z) : "") +
                  "'><td>" + r.info->name + "</td><td>" + esc(r.info->human_unit) + "</td>";
  s += "<td class='num'>" + fmt("%.6g", r.a * h) + " ± " + fmt("%.2g", r.sa * h) +
       "</td><td class='num'>" + fmt("%.6g", r.b * h) + " ± " + fmt("%.2g", r.sb * h) + "</td>";
  if (!r.compared) return s + "<td colspan='3' class='muted'>not compared</td></tr>\n";
  const bool far = std::isfinite(r.z) && std::abs(r.z) > 3;
  return s + "<td class='num'>" + fmt("%+.4g", r.diff * h) + "</td><td class='num'>" +
         fmt("%.2g", r.sigma * h) + "</td><td class='num" + (far ? " far" : "") + "'>" +
         (std::isfinite(r.z) ? fmt("%+.2f σ", r.z) : "-") + "</td></tr>\n";
}

std::string compare_html(const Side& a, const Side& b, const std::vector<Row>& rows,
                         db::history::Method m, const Params& query) {
  const std::string ia = std::to_string(a.details.run.run_id),
                    ib = std::to_string(b.details.run.run_id);
  std::string s = "<h1>Run " + ia + " and run " + ib + " (" + method_label(m) + ")</h1>\n";
  s += request_form("/compare", query,
                    "Runs to compare (a, b) and the method (ains, nlsq, legacy):");
  s += run_table({a.details.run, b.details.run}, true, "compared-runs");
  s += "<table id='compare' data-a='" + ia + "' data-b='" + ib + "' data-method='" +
       db::history::to_string(m) + "'>\n<tr><th>parameter</th><th>unit</th><th class='num'>run " +
       ia + " ± 1σ</th><th class='num'>run " + ib +
       " ± 1σ</th><th class='num'>B − A</th><th class='num'>σ (combined)</th><th "
       "class='num'>(B − A) / σ</th></tr>\n";
  int far = 0;
  for (const Row& r : rows) {
    s += row_html(r);
    far += r.compared && std::isfinite(r.z) && std::abs(r.z) > 3;
  }
  s += "</table>\n<p id='compare-summary' data-beyond-3-sigma='" + std::to_string(far) + "'>" +
       std::to_string(far) +
       " parameter(s) differ by more than 3σ; σ combines both runs' 1σ (independent "
       "calibrations).</p>\n";
  return s +
         download_links("/compare?a=" + ia + "&b=" + ib + "&method=" + db::history::to_string(m));
}

}  // namespace

Reply compare_reply(const History& history, const Params& query) {
  check_known_params(query, {"a", "b", "method", "format"});
  const Format format = parse_format(query);
  const std::string ta = trimmed(query_value(query, "a")), tb = trimmed(query_value(query, "b"));
  if (ta.empty() || tb.empty()) {
    if (format != Format::kHtml) bad_input(ta.empty() ? "a" : "b", "no run given");
    return {page("Compare runs",
                 "<h1>Compare two runs</h1>\n" +
                     request_form("/compare", query,
                                  "Two run numbers (a, b) and the method (ains, nlsq, legacy):"))};
  }
  const db::history::Method m = method_field(query_value(query, "method"));
  const Side a = side(history, "a", run_id_field("a", ta), m);
  const Side b = side(history, "b", run_id_field("b", tb), m);
  const std::vector<Row> rows = compare_rows(a, b);
  const std::string name = "compare-" + ta + "-" + tb;
  if (format == Format::kJson)
    return {compare_json(a, b, rows, m), "application/json", name + ".json"};
  if (format == Format::kCsv) return {compare_csv(rows), "text/csv; charset=utf-8", name + ".csv"};
  return {page("Compare runs " + ta + " and " + tb, compare_html(a, b, rows, m, query))};
}

}  // namespace imucal::tools::stationweb
