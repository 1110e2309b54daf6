#include "tools/report/diagnosis_text.hpp"

#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <limits>
#include <vector>

namespace imucal::tools::report {

// Named, not only anonymous: the report's files compile in one unity batch, where the HTML page
// has helpers of the same short names.
namespace {
namespace diagnosis_text {

using nlohmann::json;

/// printf onto the end of `out`: the report keeps the exact formats imucal diagnose printed with
/// printf before it read the JSON (its output is the reference, issue #49 item 4).
__attribute__((format(printf, 2, 3))) void add(std::string& out, const char* format, ...) {
  va_list args, again;
  va_start(args, format);
  va_copy(again, args);
  const int n = std::vsnprintf(nullptr, 0, format, args);  // a summary has no length limit
  va_end(args);
  if (n > 0) {
    const std::size_t at = out.size();
    out.resize(at + static_cast<std::size_t>(n) + 1);
    std::vsnprintf(&out[at], static_cast<std::size_t>(n) + 1, format, again);
    out.resize(at + static_cast<std::size_t>(n));
  }
  va_end(again);
}

/// A number of the JSON; NaN where it is null or missing (diagnosis_to_json writes every
/// non-finite figure as null, and the text prints it as the struct's NaN printed).
double value(const json& o, const char* key) {
  if (!o.is_object()) return std::numeric_limits<double>::quiet_NaN();
  const auto it = o.find(key);
  if (it == o.end() || !it->is_number()) return std::numeric_limits<double>::quiet_NaN();
  return it->get<double>();
}

std::string text(const json& o, const char* key) {
  if (!o.is_object()) return "";
  const auto it = o.find(key);
  return it != o.end() && it->is_string() ? it->get<std::string>() : "";
}

bool flag(const json& o, const char* key) {
  if (!o.is_object()) return false;
  const auto it = o.find(key);
  return it != o.end() && it->is_boolean() && it->get<bool>();
}

const json& list(const json& o, const char* key) {
  static const json empty = json::array();
  if (!o.is_object()) return empty;
  const auto it = o.find(key);
  return it != o.end() && it->is_array() ? *it : empty;
}

const json& object(const json& o, const char* key) {
  static const json empty = json::object();
  if (!o.is_object()) return empty;
  const auto it = o.find(key);
  return it != o.end() && it->is_object() ? *it : empty;
}

/// Whether `d` has `key` at all: a run's stored summary (db::archive::diagnosis_summary_json, what
/// stationweb shows) has no segments, candidates, whiteness or chi2, and its text leaves them out
/// rather than print empty tables and NaN (issue #52 item 6).
bool has(const json& d, const char* key) { return d.is_object() && d.contains(key); }

/// A sea run's residuals are the navigation filter's GNSS innovations, not rests and moves.
bool at_sea(const json& d) { return text(d, "residuals") == "gnss_innovations"; }

/// The residual components' JSON keys in their order ("accel_x" ... "gyro_z"; at sea
/// "gnss_north", "gnss_east").
std::vector<std::string> components(const json& d) {
  std::vector<std::string> keys;
  for (const json& k : list(d, "components"))
    if (k.is_string()) keys.push_back(k.get<std::string>());
  return keys;
}

/// "accel_x" -> "accel x": the name calib/diagnosis gives the component beside its key.
std::string component_name(std::string key) {
  std::replace(key.begin(), key.end(), '_', ' ');
  return key;
}

void run_line(std::string& out, const json& d) {
  std::string what = text(d, "archive");
  if (d.contains("run_id") && d["run_id"].is_number_integer())
    what = std::to_string(d["run_id"].get<long long>()) + " (archive " + what + ")";
  add(out, "run %s (serial %s, ", what.c_str(), text(d, "serial").c_str());
  // An imported recording has no sequence: no empty clause for it (issue #50 item 5).
  if (!text(d, "sequence").empty()) add(out, "sequence %s, ", text(d, "sequence").c_str());
  if (d.contains("samples") && d["samples"].is_number_unsigned())
    add(out, "%zu samples, ", d["samples"].get<std::size_t>());
  if (has(d, "segments"))
    add(out, "%zu segments)\n", list(d, "segments").size());
  else
    add(out, "stored summary)\n");
  add(out, "verdict: %s -- %s\n", text(d, "verdict").c_str(), text(d, "summary").c_str());
}

/// The explaining effects per parameter (the text said only the norm; issue #19 item 6).
void parameters(std::string& out, const json& params) {
  const char* sep = " ";
  for (const json& p : params) {
    const double sigma = value(p, "sigma");
    if (!(sigma > 0.0)) continue;  // shape parameters (searched on a grid) and unfitted ones
    add(out, "%s%s = %.3g +- %.2g %s", sep, text(p, "name").c_str(), value(p, "value"), sigma,
        text(p, "unit").c_str());
    sep = ", ";
  }
  add(out, "\n");
}

/// A stored summary has no candidates to look the best effect up in: its best (and second) effect
/// with size and unit as stored. Nothing for a full diagnosis, whose candidate table has them.
void best_of_summary(std::string& out, const json& d) {
  if (has(d, "candidates")) return;
  for (const char* key : {"best", "second"}) {
    const json& b = object(d, key);
    if (!b.contains("effect")) continue;
    add(out, "%s effect: %s = %.3g +- %.2g %s\n", key, text(b, "effect").c_str(),
        value(b, "magnitude"), value(b, "sigma"), text(b, "unit").c_str());
  }
  for (const json& a : list(d, "ambiguous"))
    if (a.is_string())
      add(out, "  not told apart from the best: %s\n", a.get<std::string>().c_str());
}

/// The explained set step by step (sizes from its joint fit) or, for an ambiguous set, each
/// member's own fit.
void explained_by(std::string& out, const json& d) {
  const json& steps = list(d, "steps");
  if (text(d, "verdict") == "explained" && !steps.empty()) {
    add(out, "explained step by step (sizes fitted jointly):\n");
    for (std::size_t i = 0; i < steps.size(); ++i) {
      const json& s = steps[i];
      // A set this sequence cannot tell apart, named as the set (issue #49 item 2).
      std::string name = text(s, "effect");
      for (const json& o : list(s, "set"))
        if (o.is_string()) name += " | " + o.get<std::string>();
      add(out,
          "  %zu. %s = %.3g +- %.2g %s (p %.2g given the steps before; chi2/dof -> %.3f, "
          "held-out gap -> %.3f)\n",
          i + 1, name.c_str(), value(s, "magnitude"), value(s, "sigma"), text(s, "unit").c_str(),
          value(s, "p_value"), value(s, "gap_after"), value(s, "held_out_after"));
      if (has(s, "parameters")) {  // a stored summary's steps have none
        add(out, "    ");
        parameters(out, list(s, "parameters"));
      }
      if (!text(s, "note").empty()) add(out, "    (%s)\n", text(s, "note").c_str());
    }
    return;
  }
  best_of_summary(out, d);
  for (const json& name : list(d, "explained_by"))
    for (const json& c : list(d, "candidates")) {
      if (!name.is_string() || text(c, "effect") != name.get<std::string>()) continue;
      add(out, "  %s:", text(c, "effect").c_str());
      parameters(out, list(c, "parameters"));
    }
}

/// The effects the search chose whose place the final joint fit does not support (issue #49 item
/// 1), with their size there and every test they failed.
void not_supported(std::string& out, const json& d) {
  const json& u = list(d, "not_supported");
  if (u.empty()) return;
  add(out, "fitted, not supported (dropped from the explanation):\n");
  for (const json& e : u)
    add(out, "  %s = %.3g +- %.2g %s: %s\n", text(e, "effect").c_str(), value(e, "magnitude"),
        value(e, "sigma"), text(e, "unit").c_str(), text(e, "reason").c_str());
}

/// The overall gap, against what the model predicts for this run (its simulated twin) where there
/// is one.
void overall(std::string& out, const json& d) {
  const json& o = object(d, "overall");
  const int dof = o.contains("dof") && o["dof"].is_number() ? o["dof"].get<int>() : 0;
  if (!has(o, "chi2")) {  // a stored summary: the ratio, its expectation and p only
    add(out, "overall gap: chi2/dof %.3f (expected 1 +- %.3f; p %.2g)\n", value(o, "gap"),
        value(o, "sigma"), value(o, "p_value"));
    return;
  }
  add(out, "overall gap: chi2/dof %.3f (chi2 %.1f, dof %d; expected 1 +- %.3f; p %.2g)",
      value(o, "gap"), value(o, "chi2"), dof, value(o, "sigma"), value(o, "p_value"));
  if (object(d, "best").contains("effect") || !list(d, "ambiguous").empty())
    add(out, " -> %.3f with the best effect", value(o, "gap_after_best"));
  if (std::isfinite(value(o, "simulated_gap")))
    add(out,
        "\nsimulated twin (this trajectory, the calibrated model, the declared noise): chi2/dof "
        "%.3f\n",
        value(o, "simulated_gap"));
  else if (at_sea(d))
    add(out,
        "\nsea run: the residuals are the navigation filter's GNSS innovations with the sensor "
        "parameters held at the calibration (the deck moves the unit during its rests); no "
        "simulated twin\n");
  else
    add(out,
        "\ntable-free run: each rest's attitude is an unknown of the fit (what such a run "
        "observes: gravity's magnitude and the Earth rate at each rest, gravity and attitude "
        "carried by the gyros across each move, no velocity gained); no simulated twin\n");
}

void whiteness_and_held_out(std::string& out, const json& d) {
  if (!has(d, "whiteness")) {
    // a stored summary: no rest-sample figures to report
  } else if (at_sea(d)) {
    add(out, "rest samples: not judged at sea (the deck turns the unit during its rests)\n");
  } else {
    add(out, "rest samples, lag-1 autocorrelation (z vs declared noise):");
    const json& axes = object(object(d, "whiteness"), "axes");
    for (const std::string& key : components(d)) {
      const json& a = object(axes, key.c_str());
      add(out, " %s %+.3f (%+.1f)", component_name(key).c_str(), value(a, "lag1_autocorr"),
          value(a, "lag1_z"));
    }
    add(out, "\n");
  }
  if (!has(d, "held_out")) return;
  const json& h = object(d, "held_out");
  if (h.contains("gap_after") && h["gap_after"].is_number()) {
    add(out, "held-out gap (fit on the other segments): %.3f -> %.3f", value(h, "gap_before"),
        value(h, "gap_after"));
    if (h.contains("gap_after_pair") && h["gap_after_pair"].is_number())
      add(out, " -> %.3f with the whole set", value(h, "gap_after_pair"));
    add(out, " (shrinkage %.0f %%; 1 = as the model predicts)\n", 100.0 * value(h, "shrinkage"));
  } else {
    add(out, "held-out gap (fit on the other segments): %.3f (1 = as the model predicts)\n",
        value(h, "gap_before"));
  }
}

/// Told apart from the base parameters (the JSON's "separable" also asks it of the other
/// candidates; the table's size column asks only this, as it did when it read the struct).
bool separable_from_base(const json& c) {
  if (c.contains("separable_from_base")) return flag(c, "separable_from_base");
  return flag(c, "separable");
}

/// Every candidate in the diagnosis' rank order (findings first, by held-out gap; then the
/// separable ones by score), each column labelled.
void candidates(std::string& out, const json& d) {
  if (!has(d, "candidates")) return;
  add(out, "\ncandidate effects, ranked (score = BIC gain; LR = chi2 drop when added):\n");
  add(out, "  %-24s %10s %10s %3s %9s  %-28s %9s  %s\n", "effect", "score", "LR", "k", "p",
      "magnitude +- 1 sigma", "held-out", "note");
  for (const json& c : list(d, "candidates")) {
    const bool separable = separable_from_base(c);
    char mag[64] = "-";
    if (separable)
      std::snprintf(mag, sizeof mag, "%.3g +- %.2g %s", value(c, "magnitude"), value(c, "sigma"),
                    text(c, "unit").c_str());
    char held[32] = "-";
    if (separable) std::snprintf(held, sizeof held, "%.3f", value(c, "held_out_gap"));
    const int k = c.contains("k") && c["k"].is_number() ? c["k"].get<int>() : 0;
    add(out, "  %-24s %10.1f %10.1f %3d %9.2g  %-28s %9s  %s%s\n", text(c, "effect").c_str(),
        value(c, "bic_gain"), value(c, "lr"), k, value(c, "p_value"), mag, held,
        flag(c, "significant")        ? "significant. "
        : flag(c, "in_ambiguous_set") ? "significant as a set. "
                                      : "",
        text(c, "note").c_str());
  }
}

/// The component of segment `g` with the largest |z| (a non-finite one gives way).
std::size_t worst_component(const json& g, const std::vector<std::string>& keys) {
  const json& z = object(g, "z");
  std::size_t worst = 0;
  for (std::size_t c = 1; c < keys.size(); ++c)
    if (std::abs(value(z, keys[c].c_str())) > std::abs(value(z, keys[worst].c_str())) ||
        !std::isfinite(value(z, keys[worst].c_str())))
      worst = c;
  return worst;
}

void segments(std::string& out, const json& d) {
  if (!has(d, "segments")) return;
  const std::vector<std::string> keys = components(d);
  std::vector<const json*> s;
  for (const json& g : list(d, "segments")) s.push_back(&g);
  std::sort(s.begin(), s.end(),
            [](const json* a, const json* b) { return value(*a, "nis") > value(*b, "nis"); });
  if (at_sea(d))
    add(out, "\nsegments with the largest gap (NIS over their GNSS fixes; about their rows):\n");
  else
    add(out, "\nsegments with the largest gap (NIS; about %zu expected under the model):\n",
        keys.size());
  add(out, "  %-26s %8s %8s %8s %9s %9s  %s\n", "segment", "t0 [s]", "NIS", "NIS sim", "p",
      "outer/inner", at_sea(d) ? "largest |z| (GNSS axis)" : "largest |z| (sensor axis)");
  for (std::size_t i = 0; i < s.size() && i < 8 && !keys.empty(); ++i) {
    const json& g = *s[i];
    const std::size_t worst = worst_component(g, keys);
    char twin[16] = "-";  // a table-free run has no twin
    if (std::isfinite(value(g, "nis_sim")))
      std::snprintf(twin, sizeof twin, "%.2f", value(g, "nis_sim"));
    char angles[24] = "-";  // table-free: no table angles
    if (std::isfinite(value(g, "outer_deg")))
      std::snprintf(angles, sizeof angles, "%4.0f/%-4.0f", value(g, "outer_deg"),
                    value(g, "inner_deg"));
    add(out, "  %-26s %8.1f %8.2f %8s %9.2g %9s  %+.2f (%s)\n", text(g, "label").c_str(),
        value(g, "t0_s"), value(g, "nis"), twin, value(g, "p_value"), angles,
        value(object(g, "z"), keys[worst].c_str()), component_name(keys[worst]).c_str());
  }
}

void moved_and_remaining(std::string& out, const json& d) {
  const json& moved = list(d, "moved_parameters");
  if (!moved.empty()) {
    const std::string best = text(object(d, "best"), "effect");
    add(out, "\ncalibration parameters that move when %s is added:\n",
        best.empty() ? "the best effect" : best.c_str());
    for (const json& m : moved)
      add(out, "  %-24s %+8.2f sigma  (%+.3g %s)\n", text(m, "name").c_str(),
          value(m, "shift_sigma"), value(m, "shift"), text(m, "unit").c_str());
  }
  const json& remaining = list(d, "remaining");
  if (!remaining.empty() && text(d, "verdict") != "explained") {
    add(out, "\nwhere the gap remains (|z| > 3):\n");
    for (const json& r : remaining)
      add(out, "  %-40s z %+.2f\n", text(r, "where").c_str(), value(r, "z"));
  }
}

}  // namespace diagnosis_text
}  // namespace

std::string diagnosis_report_text(const nlohmann::json& diagnosis) {
  namespace t = diagnosis_text;
  std::string out;
  t::run_line(out, diagnosis);
  t::explained_by(out, diagnosis);
  t::not_supported(out, diagnosis);
  t::overall(out, diagnosis);
  t::whiteness_and_held_out(out, diagnosis);
  t::candidates(out, diagnosis);
  t::segments(out, diagnosis);
  t::moved_and_remaining(out, diagnosis);
  return out;
}

}  // namespace imucal::tools::report
