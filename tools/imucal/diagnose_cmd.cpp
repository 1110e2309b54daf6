#include "tools/imucal/diagnose_cmd.hpp"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <sstream>
#include <stdexcept>

#include "calib/ains/ains.hpp"
#include "calib/diagnosis/diagnosis.hpp"
#include "calib/diagnosis/gap_model.hpp"
#include "calib/legacy/legacy.hpp"
#include "calib/nlsq/nlsq.hpp"
#include "db/archive/archive_input.hpp"
#include "db/archive/diagnosis_json.hpp"
#include "db/archive/io_util.hpp"
#include "db/archive/run_archive.hpp"
#include "tools/imucal/exit_codes.hpp"
#include "tools/report/diagnosis_report.hpp"

namespace imucal::tools::imucal {
using namespace tools::report;

namespace {

std::vector<calib::effects::EffectId> parse_candidates(const std::string& list) {
  try {
    return calib::effects::parse_effect_list(list);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(std::string("--candidates: ") + e.what());
  }
}

void print_candidates(const calib::diagnosis::DiagnosisResult& d) {
  std::printf("\ncandidate effects, ranked (score = BIC gain; LR = chi2 drop when added):\n");
  std::printf("  %-24s %10s %10s %3s %9s  %-28s %9s  %s\n", "effect", "score", "LR", "k", "p",
              "magnitude +- 1 sigma", "held-out", "note");
  for (const auto& c : d.candidates) {
    char mag[64] = "-";
    if (c.separable)
      std::snprintf(mag, sizeof mag, "%.3g +- %.2g %s", c.magnitude, c.magnitude_sigma,
                    c.unit.c_str());
    char held[32] = "-";
    if (c.separable) std::snprintf(held, sizeof held, "%.3f", c.held_out_gap);
    std::printf("  %-24s %10.1f %10.1f %3d %9.2g  %-28s %9s  %s%s\n", c.name.c_str(), c.bic_gain,
                c.lr, c.k, c.p_value, mag, held,
                c.significant        ? "significant. "
                : c.in_ambiguous_set ? "significant as a set. "
                                     : "",
                c.note.c_str());
  }
}

/// The explaining effects per parameter (the text said only the norm; issue #19 item 6).
void print_params(const std::vector<calib::diagnosis::CandidateParam>& params) {
  const char* sep = " ";
  for (const auto& p : params) {
    if (!(p.sigma > 0.0)) continue;  // shape parameters (searched on a grid) and unfitted ones
    std::printf("%s%s = %.3g +- %.2g %s", sep, p.name.c_str(), p.value, p.sigma, p.unit.c_str());
    sep = ", ";
  }
  std::printf("\n");
}

/// The explained set step by step (sizes from its joint fit) or, for an ambiguous set, each
/// member's own fit.
void print_explained_by(const calib::diagnosis::DiagnosisResult& d) {
  if (d.verdict == "explained" && !d.steps.empty()) {
    std::printf("explained step by step (sizes fitted jointly):\n");
    for (size_t i = 0; i < d.steps.size(); ++i) {
      const calib::diagnosis::DiagnosisStep& s = d.steps[i];
      std::printf(
          "  %zu. %s = %.3g +- %.2g %s (p %.2g given the steps before; chi2/dof -> %.3f, "
          "held-out gap -> %.3f)\n    ",
          i + 1, s.effect.c_str(), s.magnitude, s.magnitude_sigma, s.unit.c_str(), s.p_value,
          s.gap_after, s.held_out_after);
      print_params(s.params);
      if (!s.note.empty()) std::printf("    (%s)\n", s.note.c_str());
    }
    return;
  }
  for (const std::string& name : d.explained_by)
    for (const auto& c : d.candidates) {
      if (c.name != name) continue;
      std::printf("  %s:", c.name.c_str());
      print_params(c.params);
    }
}

void print_segments(const calib::diagnosis::DiagnosisResult& d) {
  std::vector<const calib::diagnosis::SegmentGap*> s;
  for (const auto& g : d.segments) s.push_back(&g);
  std::sort(s.begin(), s.end(), [](auto* a, auto* b) { return a->nis > b->nis; });
  if (d.innovation_residuals)
    std::printf("\nsegments with the largest gap (NIS over their GNSS fixes; about their rows):\n");
  else
    std::printf("\nsegments with the largest gap (NIS; about %d expected under the model):\n",
                calib::diagnosis::kGapRowsPerSegment);
  std::printf("  %-26s %8s %8s %8s %9s %9s  %s\n", "segment", "t0 [s]", "NIS", "NIS sim", "p",
              "outer/inner",
              d.innovation_residuals ? "largest |z| (GNSS axis)" : "largest |z| (sensor axis)");
  for (size_t i = 0; i < s.size() && i < 8; ++i) {
    const auto& g = *s[i];
    int worst = 0;
    for (int c = 1; c < static_cast<int>(d.components.size()); ++c)
      if (std::abs(g.z[static_cast<size_t>(c)]) > std::abs(g.z[static_cast<size_t>(worst)]) ||
          !std::isfinite(g.z[static_cast<size_t>(worst)]))
        worst = c;
    char twin[16] = "-";  // a table-free run has no twin
    if (std::isfinite(g.nis_twin)) std::snprintf(twin, sizeof twin, "%.2f", g.nis_twin);
    char angles[24] = "-";  // table-free: no table angles
    if (std::isfinite(g.segment.outer_deg))
      std::snprintf(angles, sizeof angles, "%4.0f/%-4.0f", g.segment.outer_deg,
                    g.segment.inner_deg);
    std::printf("  %-26s %8.1f %8.2f %8s %9.2g %9s  %+.2f (%s)\n", g.segment.label().c_str(),
                g.segment.t0_s, g.nis, twin, g.p_value, angles, g.z[static_cast<size_t>(worst)],
                d.components[static_cast<size_t>(worst)].c_str());
  }
}

void print_human(const calib::diagnosis::DiagnosisResult& d, const db::archive::RunArchive& ar,
                 size_t samples) {
  std::printf("run %s (serial %s, sequence %s, %zu samples, %zu segments)\n", ar.origin.c_str(),
              ar.info.serial.c_str(), ar.info.sequence_name.c_str(), samples, d.segments.size());
  std::printf("verdict: %s -- %s\n", d.verdict.c_str(), d.summary.c_str());
  print_explained_by(d);
  std::printf("overall gap: chi2/dof %.3f (chi2 %.1f, dof %d; expected 1 +- %.3f; p %.2g)",
              d.overall_gap, d.chi2, d.dof, d.overall_sigma, d.overall_p);
  if (d.best || !d.ambiguous.empty())
    std::printf(" -> %.3f with the best effect", d.gap_after_best);
  if (std::isfinite(d.twin_gap))
    std::printf(
        "\nsimulated twin (this trajectory, the calibrated model, the declared noise): chi2/dof "
        "%.3f\n",
        d.twin_gap);
  else if (d.innovation_residuals)
    std::printf(
        "\nsea run: the residuals are the navigation filter's GNSS innovations with the sensor "
        "parameters held at the calibration (the deck moves the unit during its rests); no "
        "simulated twin\n");
  else
    std::printf(
        "\ntable-free run: each rest's attitude is an unknown of the fit (what such a run "
        "observes: gravity's magnitude and the Earth rate at each rest, gravity and attitude "
        "carried by the gyros across each move, no velocity gained); no simulated twin\n");
  if (d.innovation_residuals) {
    std::printf("rest samples: not judged at sea (the deck turns the unit during its rests)\n");
  } else {
    std::printf("rest samples, lag-1 autocorrelation (z vs declared noise):");
    for (int c = 0; c < calib::diagnosis::kGapRowsPerSegment; ++c)
      std::printf(" %s %+.3f (%+.1f)", calib::diagnosis::gap_component_name(c),
                  d.whiteness.lag1_autocorr[static_cast<size_t>(c)],
                  d.whiteness.lag1_z[static_cast<size_t>(c)]);
    std::printf("\n");
  }
  if (d.held_out.has_after) {
    std::printf("held-out gap (fit on the other segments): %.3f -> %.3f", d.held_out.gap_before,
                d.held_out.gap_after);
    if (d.held_out.has_pair) std::printf(" -> %.3f with the whole set", d.held_out.gap_after_pair);
    std::printf(" (shrinkage %.0f %%; 1 = as the model predicts)\n", 100.0 * d.held_out.shrinkage);
  } else {
    std::printf("held-out gap (fit on the other segments): %.3f (1 = as the model predicts)\n",
                d.held_out.gap_before);
  }
  print_candidates(d);
  print_segments(d);
  if (!d.moved.empty()) {
    std::printf("\ncalibration parameters that move when %s is added:\n",
                d.best ? d.candidates[*d.best].name.c_str() : "the best effect");
    for (const auto& m : d.moved)
      std::printf("  %-24s %+8.2f sigma  (%+.3g %s)\n", m.name.c_str(), m.shift_sigma, m.shift,
                  m.unit.c_str());
  }
  if (!d.remaining.empty() && d.verdict != "explained") {
    std::printf("\nwhere the gap remains (|z| > 3):\n");
    for (const auto& [w, z] : d.remaining) std::printf("  %-40s z %+.2f\n", w.c_str(), z);
  }
}

}  // namespace

CLI::App* add_diagnose_command(CLI::App& app, DiagnoseArgs& a) {
  auto* c = app.add_subcommand(
      "diagnose", "sim-to-real gap: where a run departs from the model, which effect explains it");
  c->add_option("dir", a.dir, "run archive directory")->required();
  c->add_flag("--json", a.json, "print one JSON object");
  c->add_option(
      "--report", a.report_dir,
      "also write OUTDIR/report.html (heat map, ranking, before/after) and OUTDIR/diagnosis.json");
  c->add_option(
      "--candidates", a.candidates,
      "comma-separated effects to consider (default: the whole catalogue; see imucal effects)");
  c->add_option("--grade", a.grade,
                "navigation|tactical|mems: the unit's grade instead of run.toml's [prior] grade "
                "(field runs: the rest detector; every run: how large an effect may plausibly be)")
      ->check(CLI::IsMember({"navigation", "tactical", "mems"}));
  c->add_option("--min-rest-s", a.min_rest_s,
                "field runs: the shortest rest kept, s (default: the detector's)")
      ->check(CLI::Range(0.5, 600.0));
  c->add_option("--first-rest-s", a.first_rest_s,
                "field runs: the first rest must last this long, s (default: the grade's rule, "
                "as calibrate)")
      ->check(CLI::Range(0.5, 600.0));
  return c;
}

namespace {

/// --report OUTDIR must be a directory or not exist yet (checked before any work).
void check_report_dir(const std::string& dir) {
  if (dir.empty()) return;
  std::error_code ec;
  if (std::filesystem::exists(dir, ec) && !std::filesystem::is_directory(dir, ec))
    throw std::invalid_argument("--report " + dir + ": exists and is not a directory");
}

/// OUTDIR/report.html and OUTDIR/diagnosis.json, each written atomically; OUTDIR created only now
/// that the diagnosis has succeeded.
void write_report(const std::string& dir, const nlohmann::json& j) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw std::runtime_error("--report " + dir + ": cannot create it: " + ec.message());
  db::archive::write_file_atomic(dir + "/diagnosis.json", j.dump(2) + "\n");
  db::archive::write_file_atomic(dir + "/report.html", diagnosis_report_html(j));
}

}  // namespace

int cmd_diagnose(const DiagnoseArgs& a) {
  const std::vector<calib::effects::EffectId> ids =
      parse_candidates(a.candidates);  // before any work
  check_report_dir(a.report_dir);
  db::archive::RunArchive ar = db::archive::read_archive(a.dir);
  if (!a.grade.empty()) ar.info.grade = *calib::core::parse_grade(a.grade);
  if (a.min_rest_s > 0.0) ar.info.min_rest_s = a.min_rest_s;
  if (a.first_rest_s > 0.0) ar.info.first_rest_s = a.first_rest_s;
  calib::diagnosis::DiagnosisInput in;
  in.cal = db::archive::to_calibration_input(ar);
  try {
    calib::diagnosis::GapModel::check_setting(in.cal);  // before calibrating it
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(a.dir + ": " + e.what());
  }
  if (ar.info.reference == db::archive::ReferenceKind::kTable)
    in.geometry = ar.info.table.geometry();
  // The model under test: a table run's NLSQ calibration; a land run's multi-position one, which
  // needs no prior beyond the grade's; a sea run's AINS (a rocking deck has no still rest for the
  // multi-position method). The diagnosis refits the base either way.
  const bool table_free = !in.cal.has_reference_attitude();
  const bool sea = in.cal.setting == calib::core::Setting::kSea;
  const char* method = sea ? "ains" : table_free ? "legacy" : "nlsq";
  const calib::core::CalibrationResult cal = sea          ? calib::ains::calibrate_ains(in.cal)
                                             : table_free ? calib::legacy::calibrate_legacy(in.cal)
                                                          : calib::nlsq::calibrate_nlsq(in.cal);
  calib::diagnosis::DiagnosisOptions opt;
  opt.candidates = ids;
  const calib::diagnosis::DiagnosisResult d = calib::diagnosis::diagnose(in, cal.params, opt);
  const nlohmann::json j = db::archive::diagnosis_run_json(d, a.dir, ar.info, in.cal, method);
  if (!a.report_dir.empty()) write_report(a.report_dir, j);
  if (a.json) {
    std::cout << j.dump(2) << '\n';
  } else {
    print_human(d, ar, in.cal.imu.size());
  }
  return d.verdict == "unexplained" ? kExitReview : 0;
}

}  // namespace imucal::tools::imucal
