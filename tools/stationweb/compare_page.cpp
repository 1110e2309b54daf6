// "/compare?a=N&b=M[&method=ains|nlsq|legacy][&format=csv|json]": two runs side by side (issue #52
// item 8) — each parameter's value ± 1σ of run A and of run B (the same method's), their
// difference B − A, its σ and the difference in those σ. Issue #52 (QA's audit, F2/F3) says when
// that figure means nothing, per parameter (`status`):
//   compared          two captures: independent estimates, σ = sqrt(σA² + σB²), z = (B − A)/σ
//   not determined    a run does not determine it (its `unobservable`): no value, no difference
//   different body frames  a misalignment of a housing-frame run against one in the accelerometer
//                     triad's frame (calib/core/body_frame.hpp): a change of frame rotates
//                     I + M, so the off-diagonal terms differ by the housing angle (~100 µrad)
//                     whatever the unit did. A scale factor (the diagonal) moves only to second
//                     order, by at most 2·max|M_off|·|φ| + |φ|²/2 with φ the housing angle (the
//                     antisymmetric part of the housing run's accel_M): compared while that is
//                     below a tenth of the combined σ, else not. Converting a run into the other
//                     frame needs its covariance, which the history does not keep.
//   same capture      a run and its reprocess (the reprocessed_from chain, or the same archive):
//                     the same samples, so the two estimates share their noise and sqrt(σA² + σB²)
//                     does not hold (the σ of their difference is unknown, and zero when nothing in
//                     the processing changed): B − A is shown as what the reprocessing changed, no
//                     z and no count beyond 3σ.
// The numbers in SI and full precision in data attributes, CSV and JSON (null / empty where there
// is no number).
#include <algorithm>
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

constexpr const char* kCompared = "compared";
constexpr const char* kNotDetermined = "not determined";
constexpr const char* kOtherFrames = "different body frames";
constexpr const char* kSameCapture = "same capture";

struct Row {
  const calib::core::ParamInfo* info;
  std::string status = kCompared;           ///< see the file's comment
  bool a_det = true, b_det = true;          ///< the run determines the parameter
  double a = 0, sa = 0, b = 0, sb = 0;      ///< SI
  double diff = NAN, sigma = NAN, z = NAN;  ///< SI; NaN where the status gives none
  bool compared() const { return status == kCompared; }
};

/// Whether the two runs calibrated the same capture: one reprocessed (maybe through a chain) from
/// the other, both from one run, or the same archive by its digest.
bool same_capture(const History& history, const db::history::RunRecord& a,
                  const db::history::RunRecord& b) {
  if (!a.archive_sha256.empty() && a.archive_sha256 == b.archive_sha256) return true;
  auto root = [&](db::history::RunRecord r) {
    for (int hops = 0; r.reprocessed_from && hops < 1000; ++hops) {
      try {
        r = history.repo->show(*r.reprocessed_from).run;
      } catch (const db::history::NotFound&) {
        break;
      }
    }
    return r.run_id;
  };
  return root(a) == root(b);
}

/// The housing angle φ (rad) of a housing-frame result: the rotation that makes I + accel_M
/// symmetric, to first order the antisymmetric part of accel_M.
double housing_angle(const calib::core::ParamSet& p) {
  const auto& m = p.accel_M;
  const double x = (m(1, 2) - m(2, 1)) / 2, y = (m(0, 2) - m(2, 0)) / 2,
               z = (m(0, 1) - m(1, 0)) / 2;
  return std::sqrt(x * x + y * y + z * z);
}

double max_off_diagonal(const Eigen::Matrix3d& m) {
  double out = 0;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c)
      if (r != c) out = std::max(out, std::abs(m(r, c)));
  return out;
}

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

std::vector<Row> compare_rows(const Side& a, const Side& b, bool shared_samples) {
  using calib::core::ParamGroup;
  const calib::core::ParamVector va = a->params.to_vector(), sa = a->sigma.to_vector();
  const calib::core::ParamVector vb = b->params.to_vector(), sb = b->sigma.to_vector();
  const bool other_frames = a->body_frame != b->body_frame;
  const calib::core::ParamSet& housing =
      a->body_frame == calib::core::BodyFrame::kHousing ? a->params : b->params;
  const double phi = housing_angle(housing);
  std::vector<Row> rows;
  for (int i = 0; i < calib::core::ParamSet::kSize; ++i) {
    Row r{&calib::core::param_info(i)};
    r.a_det = !listed(a->unobservable, r.info->name);
    r.b_det = !listed(b->unobservable, r.info->name);
    r.a = va(i), r.sa = sa(i), r.b = vb(i), r.sb = sb(i);
    const ParamGroup g = r.info->group;
    const double combined = std::hypot(r.sa, r.sb);
    bool frame_moves = g == ParamGroup::kAccelMisalign || g == ParamGroup::kGyroMisalign;
    if (g == ParamGroup::kAccelScale || g == ParamGroup::kGyroScale) {
      const double m_off =
          max_off_diagonal(g == ParamGroup::kAccelScale ? housing.accel_M : housing.gyro_M);
      frame_moves = 2 * m_off * phi + phi * phi / 2 > 0.1 * combined;
    }
    if (!r.a_det || !r.b_det) {
      r.status = kNotDetermined;
    } else if (other_frames && frame_moves) {
      r.status = kOtherFrames;
    } else if (shared_samples) {
      r.status = kSameCapture;
      r.diff = r.b - r.a;
    } else {
      r.diff = r.b - r.a;
      r.sigma = combined;
      r.z = r.sigma > 0 ? r.diff / r.sigma : NAN;
    }
    rows.push_back(r);
  }
  return rows;
}

std::string compare_json(const Side& a, const Side& b, const std::vector<Row>& rows,
                         db::history::Method m, bool same) {
  nlohmann::json j = {{"method", db::history::to_string(m)},
                      {"a", station::control::run_record_json(a.details.run)},
                      {"b", station::control::run_record_json(b.details.run)},
                      {"parameters", nlohmann::json::array()}};
  auto num = [](double v) {
    return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr);
  };
  j["same_capture"] = same;
  for (const Row& r : rows)
    j["parameters"].push_back({{"name", r.info->name},
                               {"compared", r.compared()},
                               {"status", r.status},
                               {"a_si", r.a_det ? num(r.a) : nlohmann::json(nullptr)},
                               {"a_sigma_si", r.a_det ? num(r.sa) : nlohmann::json(nullptr)},
                               {"b_si", r.b_det ? num(r.b) : nlohmann::json(nullptr)},
                               {"b_sigma_si", r.b_det ? num(r.sb) : nlohmann::json(nullptr)},
                               {"diff_si", num(r.diff)},
                               {"sigma_si", num(r.sigma)},
                               {"diff_in_sigma", num(r.z)},
                               {"human_unit", r.info->human_unit},
                               {"si_to_human", r.info->si_to_human}});
  return j.dump(2) + "\n";
}

/// A CSV or attribute number: full precision, "" where there is none.
std::string cell(double v, bool has = true) { return has && std::isfinite(v) ? exact(v) : ""; }

std::string compare_csv(const std::vector<Row>& rows) {
  std::string s =
      "parameter,human_unit,compared,a_si,a_sigma_si,b_si,b_sigma_si,diff_si,"
      "sigma_si,diff_in_sigma,status\n";
  for (const Row& r : rows)
    s += r.info->name + "," + csv_field(r.info->human_unit) + "," + (r.compared() ? "yes" : "no") +
         "," + cell(r.a, r.a_det) + "," + cell(r.sa, r.a_det) + "," + cell(r.b, r.b_det) + "," +
         cell(r.sb, r.b_det) + "," + cell(r.diff) + "," + cell(r.sigma) + "," + cell(r.z) + "," +
         r.status + "\n";
  return s;
}

/// One run's cell: value ± 1σ to the σ's precision, or "not determined".
std::string value_cell(double v, double sigma, bool determined, double h) {
  if (!determined) return "<td class='num muted'>not determined</td>";
  return "<td class='num'>" + fmt_signed_to_sigma(v * h, sigma * h) + " ± " + fmt_sigma(sigma * h) +
         "</td>";
}

std::string row_html(const Row& r) {
  const double h = r.info->si_to_human;
  std::string s = "<tr data-param='" + r.info->name + "' data-compared='" +
                  (r.compared() ? "yes" : "no") + "' data-status='" + r.status + "' data-a-si='" +
                  cell(r.a, r.a_det) + "' data-b-si='" + cell(r.b, r.b_det) + "' data-diff-si='" +
                  cell(r.diff) + "' data-sigma-si='" + cell(r.sigma) + "' data-z='" + cell(r.z) +
                  "'><td>" + r.info->name + "</td><td>" + esc(r.info->human_unit) + "</td>";
  s += value_cell(r.a, r.sa, r.a_det, h) + value_cell(r.b, r.sb, r.b_det, h);
  if (r.status == kNotDetermined || r.status == kOtherFrames)
    return s + "<td colspan='3' class='muted'>not compared: " + r.status + "</td></tr>\n";
  if (r.status == kSameCapture)
    return s + "<td class='num'>" +
           fmt_signed_to_sigma(r.diff * h, std::min(r.sa, r.sb) * h, true) +
           "</td><td colspan='2' class='muted'>same capture: no σ, no z</td></tr>\n";
  const bool far = std::isfinite(r.z) && std::abs(r.z) > 3;
  return s + "<td class='num'>" + fmt_signed_to_sigma(r.diff * h, r.sigma * h, true) +
         "</td><td class='num'>" + fmt_sigma(r.sigma * h) + "</td><td class='num" +
         (far ? " far" : "") + "'>" +
         (std::isfinite(r.z) ? fmt_signed_to_sigma(r.z, 0.1, true) + " σ" : "-") + "</td></tr>\n";
}

/// What the table's figures mean for this pair (the same capture, other frames, how many beyond
/// 3σ), with the counts in data attributes.
std::string summary(const Side& a, const Side& b, const std::vector<Row>& rows, bool same) {
  int far = 0, compared = 0, frames = 0, undetermined = 0;
  for (const Row& r : rows) {
    compared += r.compared();
    far += r.compared() && std::isfinite(r.z) && std::abs(r.z) > 3;
    frames += r.status == kOtherFrames;
    undetermined += r.status == kNotDetermined;
  }
  const std::string ia = std::to_string(a.details.run.run_id),
                    ib = std::to_string(b.details.run.run_id);
  std::string s = "<p id='compare-summary' data-same-capture='" + std::string(same ? "yes" : "no") +
                  "' data-compared='" + std::to_string(compared) + "' data-beyond-3-sigma='" +
                  (same ? std::string() : std::to_string(far)) + "' data-other-frames='" +
                  std::to_string(frames) + "' data-not-determined='" +
                  std::to_string(undetermined) + "'>";
  if (same)
    s += "Runs " + ia + " and " + ib +
         " calibrated <b>the same capture</b> (one is a reprocess of the other, or both of one "
         "run: the same archive and samples). Their estimates share the samples' noise, so they "
         "are not independent: the σ of B − A is not √(σA² + σB²) (it is unknown, and zero when "
         "nothing in the processing changed). B − A is shown as what the reprocessing changed, "
         "to the smaller run's σ; no (B − A)/σ and no count beyond 3σ.";
  else
    s += count_of(far, "parameter") + (far == 1 ? " differs" : " differ") +
         " by more than 3σ of the " + std::to_string(compared) +
         " compared; σ combines both runs' 1σ, √(σA² + σB²): two separate captures are "
         "independent calibrations.";
  if (frames > 0)
    s += " " + count_of(frames, "parameter") +
         " not compared: the runs' calibrations are in <b>different body frames</b> (run " + ia +
         ": " +
         (a->body_frame == calib::core::BodyFrame::kHousing ? "housing" : "accelerometer triad") +
         ", run " + ib + ": " +
         (b->body_frame == calib::core::BodyFrame::kHousing ? "housing" : "accelerometer triad") +
         "); a change of frame rotates the misalignments by the housing angle, which only a "
         "factory run determines, so their difference says nothing about the unit. Scale factors "
         "move only to second order and are compared where that is below a tenth of their σ.";
  if (undetermined > 0)
    s += " " + count_of(undetermined, "parameter") +
         " not determined by a run (its setting cannot observe them): no value, nothing compared.";
  return s + "</p>\n";
}

std::string compare_html(const Side& a, const Side& b, const std::vector<Row>& rows,
                         db::history::Method m, const Params& query, bool same) {
  const std::string ia = std::to_string(a.details.run.run_id),
                    ib = std::to_string(b.details.run.run_id);
  std::string s = "<h1>Run " + ia + " and run " + ib + " (" + method_label(m) + ")</h1>\n";
  s += request_form("/compare", query,
                    "Runs to compare (a, b) and the method (ains, nlsq, legacy):");
  s += run_table({a.details.run, b.details.run}, true, "compared-runs");
  s += summary(a, b, rows, same);
  s += "<table id='compare' data-a='" + ia + "' data-b='" + ib + "' data-method='" +
       db::history::to_string(m) + "'>\n<tr><th>parameter</th><th>unit</th><th class='num'>run " +
       ia + " ± 1σ</th><th class='num'>run " + ib +
       " ± 1σ</th><th class='num'>B − A</th><th class='num'>σ (combined)</th><th "
       "class='num'>(B − A) / σ</th></tr>\n";
  for (const Row& r : rows) s += row_html(r);
  s += "</table>\n";
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
  const bool same = same_capture(history, a.details.run, b.details.run);
  const std::vector<Row> rows = compare_rows(a, b, same);
  const std::string name = "compare-" + ta + "-" + tb;
  if (format == Format::kJson)
    return {compare_json(a, b, rows, m, same), "application/json", name + ".json"};
  if (format == Format::kCsv) return {compare_csv(rows), "text/csv; charset=utf-8", name + ".csv"};
  return {page("Compare runs " + ta + " and " + tb, compare_html(a, b, rows, m, query, same))};
}

}  // namespace imucal::tools::stationweb
