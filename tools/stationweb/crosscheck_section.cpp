// The run page's cross-check: the stored verdict and failures, and per parameter the difference
// AINS − second method with its combined σ against the bound k·σ (ARCHITECTURE §6), as the station
// judged it (the status is the stored one: a parameter named in the stored failures is REVIEW).
#include <algorithm>
#include <cmath>

#include "calib/core/param_set.hpp"
#include "tools/stationweb/html.hpp"
#include "tools/stationweb/page_util.hpp"
#include "tools/stationweb/run_page_parts.hpp"

namespace imucal::tools::stationweb {

namespace {

const db::history::CalibrationRecord* find_method(
    const std::vector<db::history::CalibrationRecord>& cals, bool ains) {
  for (const auto& c : cals)
    if ((c.method == db::history::Method::kAins) == ains) return &c;
  return nullptr;
}

std::string status_of(const db::history::CrosscheckRecord& x,
                      const db::history::CalibrationRecord& a,
                      const db::history::CalibrationRecord& b, const std::string& name) {
  // An estimate that did not converge is no estimate to agree with (issue #52 item 2: a huge σ of
  // an unconverged NLSQ put every difference "within" its bound).
  if (!a.converged || !b.converged) return "not compared";
  if (listed(x.not_compared, name) || listed(a.unobservable, name) || listed(b.unobservable, name))
    return "not compared";
  for (const auto& f : x.failures)
    if (f.term == name) return "REVIEW";
  return "PASS";
}

std::string parameter_rows(const db::history::CrosscheckRecord& x,
                           const db::history::CalibrationRecord& a,
                           const db::history::CalibrationRecord& b) {
  const calib::core::ParamVector va = a.params.to_vector(), vb = b.params.to_vector();
  const calib::core::ParamVector sa = a.sigma.to_vector(), sb = b.sigma.to_vector();
  const bool same_frame = a.body_frame == b.body_frame;
  std::string s;
  for (int i = 0; i < calib::core::ParamSet::kSize; ++i) {
    const calib::core::ParamInfo& info = calib::core::param_info(i);
    const std::string status = status_of(x, a, b, info.name);
    const double diff = va(i) - vb(i), sigma = std::sqrt(sa(i) * sa(i) + sb(i) * sb(i));
    const bool numbers = same_frame && status != "not compared";
    s += "<tr data-param='" + info.name + "' data-status='" + status + "'";
    if (numbers) s += " data-diff-si='" + exact(diff) + "' data-sigma-si='" + exact(sigma) + "'";
    s += "><td>" + info.name + "</td><td>" + esc(info.human_unit) + "</td>";
    if (numbers)
      s += "<td class='num'>" +
           fmt_signed_to_sigma(diff * info.si_to_human, sigma * info.si_to_human) +
           "</td><td class='num'>" + fmt_sigma(sigma * info.si_to_human) + "</td><td class='num'>" +
           fmt_sigma(x.k_sigma * sigma * info.si_to_human) + "</td><td class='num'>" +
           (sigma > 0 ? fmt("%.2f", std::abs(diff) / sigma) : std::string("-")) + "</td>";
    else
      s += "<td colspan='4' class='muted'>-</td>";
    const std::string cls = status == "not compared" ? "muted" : status;
    s += "<td class='" + cls + "'>" + status + "</td></tr>\n";
  }
  return s;
}

std::string stored_findings(const db::history::CrosscheckRecord& x) {
  std::string s;
  if (!x.failures.empty()) {
    s += "<ul id='crosscheck-failures'>\n";
    for (const auto& f : x.failures)
      s += "<li data-term='" + esc(f.term) + "'>" + esc(f.detail) + "</li>\n";
    s += "</ul>\n";
  }
  if (!x.not_compared.empty()) {
    std::string names;
    for (const auto& n : x.not_compared) names += (names.empty() ? "" : ", ") + esc(n);
    s += "<p id='not-compared'>Not compared (not observable by both): " + names + "</p>\n";
  }
  return s;
}

}  // namespace

std::string crosscheck_section(const db::history::RunDetails& d) {
  std::string s = "<h2>Cross-check</h2>\n";
  if (!d.crosscheck)
    return s + "<div id='crosscheck' data-verdict=''><p>No cross-check stored.</p></div>\n";
  const db::history::CrosscheckRecord& x = *d.crosscheck;
  const db::history::CalibrationRecord* a = find_method(d.calibrations, true);
  const db::history::CalibrationRecord* b = find_method(d.calibrations, false);
  const std::string verdict = db::history::to_string(x.verdict);
  const std::string second =
      b ? (b->method == db::history::Method::kNlsq ? "NLSQ" : "legacy") : "?";
  s += "<div id='crosscheck' data-verdict='" + verdict + "' data-k-sigma='" + exact(x.k_sigma) +
       "'>\n<p>Cross-check <span class='" + verdict + "'>" + verdict + "</span> (AINS against " +
       second + ", bound " + fmt("%g", x.k_sigma) + "σ of the combined σ = √(σA² + σB²))" +
       (x.failures.empty() ? ": they agree on every compared parameter" : "") + ".</p>\n";
  s += stored_findings(x);
  if (!a || !b) return s + "<p>Only one method stored: no per-parameter comparison.</p></div>\n";
  if (!a->converged || !b->converged)
    s += "<p id='not-converged' class='REVIEW'>" +
         std::string(!a->converged && !b->converged ? "Neither method"
                     : !a->converged                ? "AINS"
                                                    : second) +
         " did not converge: no parameter is compared, whatever the bound (a diverged estimate's "
         "σ would put any difference within it).</p>\n";
  if (a->body_frame != b->body_frame)
    s +=
        "<p class='muted'>The two results are in different body frames; the station compared "
        "them in the accelerometer triad's frame, so only its per-parameter status is shown.</p>\n";
  s += "<table id='crosscheck-table'>\n<tr><th>parameter</th><th>unit</th><th class='num'>AINS − " +
       second + "</th><th class='num'>combined σ</th><th class='num'>bound " +
       fmt("%g", x.k_sigma) + "σ</th><th class='num'>|Δ|/σ</th><th>status</th></tr>\n";
  s += parameter_rows(x, *a, *b);
  return s + "</table>\n</div>\n";
}

}  // namespace imucal::tools::stationweb
