#include "tools/imucal/paper_tables_cmd.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <nlohmann/json.hpp>
#include <thread>

#include "calib/core/site_presets.hpp"
#include "calib/studies/paper/paper_tables.hpp"
#include "sequences/library.hpp"
#include "tools/imucal/progress_line.hpp"

namespace imucal::tools::imucal {

namespace {

using calib::studies::paper::PaperColumn;
constexpr double kSettingSpread = 0.25;  ///< the issue's "within 25 % of each other"

size_t col(PaperColumn c) { return static_cast<size_t>(c); }

/// Largest relative spread (max/min - 1) of the AINS means over the three settings.
double ains_spread(const std::array<double, calib::studies::paper::kNumPaperColumns>& mean) {
  const double vals[3] = {mean[col(PaperColumn::kFactoryAins)], mean[col(PaperColumn::kLandAins)],
                          mean[col(PaperColumn::kSeaAins)]};
  const double lo = *std::min_element(vals, vals + 3), hi = *std::max_element(vals, vals + 3);
  return lo > 0 ? hi / lo - 1.0 : 1e9;
}

/// The paper's mean of one column over its IMUs 1..n (n ≤ 6; the published mean for n ≥ 6), so a
/// run of fewer units is compared with the same IMU numbers, not the six-unit mean.
double paper_mean(
    const std::array<std::array<double, calib::studies::paper::kNumPaperColumns>, 7>& paper,
    PaperColumn c, size_t n) {
  if (n >= 6 || n == 0) return paper[6][col(c)];
  double sum = 0.0;
  for (size_t i = 0; i < n; ++i) sum += paper[i][col(c)];
  return sum / static_cast<double>(n);
}

/// "legacy is worse than AINS in orientation" judged against its scatter over the units: needs
/// at least kMinUnitsForRatio units (a standard error from two is no error bar).
constexpr size_t kMinUnitsForRatio = 3;

struct Findings {
  double orientation_spread = 0.0, accel_spread = 0.0;
  double legacy_orientation_ratio = 0.0;  ///< legacy / factory AINS, orientation means
  double ratio_se = 0.0;                  ///< standard error of the per-unit ratios' mean
  double paper_ratio = 0.0;               ///< the paper's, over the same IMU numbers
  size_t units = 0;
  bool ratio_judged() const { return units >= kMinUnitsForRatio; }
  /// Consistent with the paper's ratio within two standard errors of ours.
  bool ratio_holds() const {
    return !ratio_judged() || std::abs(legacy_orientation_ratio - paper_ratio) <= 2.0 * ratio_se;
  }
  bool hold() const {
    return orientation_spread <= kSettingSpread && accel_spread <= kSettingSpread && ratio_holds();
  }
};

Findings findings(const calib::studies::paper::PaperTables& t) {
  Findings f;
  f.units = t.units.size();
  f.orientation_spread = ains_spread(t.mean_orientation_mdeg);
  f.accel_spread = ains_spread(t.mean_accel_ug);
  f.legacy_orientation_ratio = t.mean_orientation_mdeg[col(PaperColumn::kFactoryLegacy)] /
                               t.mean_orientation_mdeg[col(PaperColumn::kFactoryAins)];
  // The ratio of means moves with the units' scatter: its standard error from the per-unit
  // ratios (delta method would need the covariance; the per-unit spread is what a reader sees).
  double sum = 0.0, sum2 = 0.0;
  for (const auto& u : t.units) {
    const double r = u.metrics[col(PaperColumn::kFactoryLegacy)].orientation_rmse_mdeg /
                     u.metrics[col(PaperColumn::kFactoryAins)].orientation_rmse_mdeg;
    sum += r;
    sum2 += r * r;
  }
  const double n = static_cast<double>(t.units.size());
  if (n >= 2) f.ratio_se = std::sqrt(std::max(0.0, (sum2 - sum * sum / n) / (n - 1)) / n);
  const auto& pub = calib::studies::paper::paper_published().orientation_mdeg;
  f.paper_ratio = paper_mean(pub, PaperColumn::kFactoryLegacy, f.units) /
                  paper_mean(pub, PaperColumn::kFactoryAins, f.units);
  return f;
}

/// Under a table of fewer than six units: whose mean the "Mean" row holds.
void print_mean_note(size_t n) {
  if (n < 6) std::printf("(Mean: over IMUs 1-%zu, the paper's over the same IMU numbers)\n", n);
}

double metric(const calib::studies::paper::PaperUnitResult& u, PaperColumn c, bool orientation) {
  const auto& m = u.metrics[col(c)];
  return orientation ? m.orientation_rmse_mdeg : m.accel_rmse_ug;
}

/// One factory table (I: orientation, II: acceleration): IMU#, AINS, NLSQ, legacy — each beside
/// the paper's column (its "Proprietary" is our legacy).
void print_factory_table(const calib::studies::paper::PaperTables& t, bool orientation) {
  const auto& pub = calib::studies::paper::paper_published();
  const auto& paper = orientation ? pub.orientation_mdeg : pub.accel_ug;
  std::printf("\nTABLE %s  %s performance for factory setting — %s (simulated | paper)\n",
              orientation ? "I" : "II", orientation ? "Attitude and heading" : "Acceleration",
              orientation ? "orientation RMSE (milli-°)" : "acceleration RMSE (µg)");
  std::printf("%-6s %21s %21s %21s\n", "IMU#", "AINS", "NLSQ", "Legacy | Proprietary");
  const PaperColumn cols[3] = {PaperColumn::kFactoryAins, PaperColumn::kFactoryNlsq,
                               PaperColumn::kFactoryLegacy};
  for (size_t i = 0; i < t.units.size(); ++i) {
    std::printf("%-6zu", i + 1);
    for (PaperColumn c : cols) {
      const double p = i < 6 ? paper[i][col(c)] : NAN;
      std::printf(" %9.4f | %9.4f", metric(t.units[i], c, orientation), p);
    }
    std::printf("\n");
  }
  const auto& mean = orientation ? t.mean_orientation_mdeg : t.mean_accel_ug;
  std::printf("%-6s", "Mean");
  for (PaperColumn c : cols)
    std::printf(" %9.4f | %9.4f", mean[col(c)], paper_mean(paper, c, t.units.size()));
  std::printf("\n");
  print_mean_note(t.units.size());
}

/// Tables III (land) and IV (sea): IMU#, orientation, acceleration.
void print_field_table(const calib::studies::paper::PaperTables& t, PaperColumn c,
                       const char* number, const char* setting) {
  const auto& pub = calib::studies::paper::paper_published();
  std::printf("\nTABLE %s  Calibration performance for %s setting (simulated | paper)\n", number,
              setting);
  std::printf("%-6s %25s %25s\n", "IMU#", "Orientation (milli-°)", "Acceleration (µg)");
  for (size_t i = 0; i < t.units.size(); ++i) {
    const double po = i < 6 ? pub.orientation_mdeg[i][col(c)] : NAN;
    const double pa = i < 6 ? pub.accel_ug[i][col(c)] : NAN;
    std::printf("%-6zu %11.4f | %11.4f %11.4f | %11.4f\n", i + 1, metric(t.units[i], c, true), po,
                metric(t.units[i], c, false), pa);
  }
  const size_t n = t.units.size();
  std::printf("%-6s %11.4f | %11.4f %11.4f | %11.4f\n", "Mean", t.mean_orientation_mdeg[col(c)],
              paper_mean(pub.orientation_mdeg, c, n), t.mean_accel_ug[col(c)],
              paper_mean(pub.accel_ug, c, n));
  print_mean_note(n);
}

nlohmann::json to_json(const calib::studies::paper::PaperTables& t, const Findings& f) {
  nlohmann::json units = nlohmann::json::array();
  for (const auto& u : t.units) {
    nlohmann::json cols = nlohmann::json::object();
    for (int c = 0; c < calib::studies::paper::kNumPaperColumns; ++c)
      cols[calib::studies::paper::paper_column_name(static_cast<PaperColumn>(c))] = {
          {"orientation_rmse_mdeg", u.metrics[static_cast<size_t>(c)].orientation_rmse_mdeg},
          {"accel_rmse_ug", u.metrics[static_cast<size_t>(c)].accel_rmse_ug},
          {"converged", u.converged[static_cast<size_t>(c)]}};
    units.push_back({{"imu", u.unit}, {"columns", cols}});
  }
  nlohmann::json mean = nlohmann::json::object(), paper = nlohmann::json::object();
  const auto& pub = calib::studies::paper::paper_published();
  for (int c = 0; c < calib::studies::paper::kNumPaperColumns; ++c) {
    const char* name = calib::studies::paper::paper_column_name(static_cast<PaperColumn>(c));
    mean[name] = {{"orientation_rmse_mdeg", t.mean_orientation_mdeg[static_cast<size_t>(c)]},
                  {"accel_rmse_ug", t.mean_accel_ug[static_cast<size_t>(c)]}};
    const auto pc = static_cast<PaperColumn>(c);
    paper[name] = {{"orientation_rmse_mdeg", paper_mean(pub.orientation_mdeg, pc, t.units.size())},
                   {"accel_rmse_ug", paper_mean(pub.accel_ug, pc, t.units.size())},
                   {"imus", std::min<size_t>(t.units.size(), 6)}};
  }
  return {{"sequence", t.sequence},
          {"unmodelled_effects", t.effects.names()},
          {"duration_s", t.duration_s},
          {"units", units},
          {"mean", mean},
          {"paper_mean", paper},
          {"findings",
           {{"ains_orientation_spread", f.orientation_spread},
            {"ains_accel_spread", f.accel_spread},
            {"legacy_over_ains_orientation", f.legacy_orientation_ratio},
            {"legacy_over_ains_orientation_se", f.ratio_se},
            {"paper_legacy_over_ains_orientation", f.paper_ratio},
            {"ratio_judged", f.ratio_judged()},
            {"hold", f.hold()}}},
          {"wall_s", t.wall_s}};
}

void print_findings(const Findings& f) {
  std::printf(
      "\nFindings: AINS means across factory/land/sea differ by %.0f %% (orientation) and %.0f %% "
      "(acceleration), bar %.0f %%; legacy / AINS orientation %.2f ± %.2f (paper, same IMUs: "
      "%.2f)",
      100 * f.orientation_spread, 100 * f.accel_spread, 100 * kSettingSpread,
      f.legacy_orientation_ratio, f.ratio_se, f.paper_ratio);
  if (!f.ratio_judged())
    std::printf(", not judged with %zu IMU%s (needs %zu for a scatter)", f.units,
                f.units == 1 ? "" : "s", kMinUnitsForRatio);
  else
    std::printf(", %s within 2σ", f.ratio_holds() ? "consistent" : "NOT consistent");
  std::printf(". %s\n", f.hold() ? "The paper's findings hold in kind." : "NOT as in the paper.");
}

}  // namespace

CLI::App* add_paper_tables_command(CLI::App& app, PaperTablesArgs& a) {
  auto* c = app.add_subcommand(
      "paper-tables",
      "the paper's Tables I-IV on simulated units: factory (AINS, NLSQ, legacy), land and sea "
      "(AINS), each beside the paper's figures");
  c->add_option("--units", a.units, "number of simulated IMUs (the paper had 6)")
      ->capture_default_str()
      ->check(CLI::Range(1, 100));
  c->add_option("--seed", a.seed, "seed of the units' parameters and noise")->capture_default_str();
  c->add_option("--sequence", a.sequence, "rotation sequence (name or file)")
      ->capture_default_str();
  c->add_option("--threads", a.threads, "units in parallel (0: one per core)")
      ->capture_default_str()
      ->check(CLI::Range(0, 64));
  c->add_option("--effects", a.effects,
                "none: ideal units (parameters and white noise); typical: every unit also carries "
                "the catalogue's unmodelled effects at typical sizes, as real units do; or a "
                "comma-separated choice of thermal, instability, k2")
      ->capture_default_str()
      ->check([](const std::string& v) {
        try {
          calib::studies::paper::parse_paper_effects(v);
          return std::string();
        } catch (const std::invalid_argument& e) {
          return std::string(e.what());
        }
      });
  c->add_flag("--json", a.json, "print one JSON object");
  return c;
}

int cmd_paper_tables(const PaperTablesArgs& a) {
  const sequences::MotionProfile profile =
      sequences::load_profile(sequences::resolve_sequence(a.sequence));
  calib::studies::paper::PaperTablesOptions opt;
  opt.units = a.units;
  opt.seed = a.seed;
  opt.effects = calib::studies::paper::parse_paper_effects(a.effects);
  opt.threads = a.threads > 0 ? a.threads
                              : std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
  opt.on_progress = ProgressLine("paper-tables", "units");
  const calib::studies::paper::PaperTables t =
      calib::studies::paper::run_paper_tables(profile, calib::core::demo_factory_site(), opt);
  const Findings f = findings(t);
  if (a.json) {
    std::cout << to_json(t, f).dump(2) << '\n';
    return f.hold() ? 0 : 3;
  }
  std::printf(
      "paper-tables: %zu simulated IMUs on %s (%.0f min), seed %llu, unmodelled effects %s, "
      "%.0f s\n",
      t.units.size(), t.sequence.c_str(), t.duration_s / 60.0,
      static_cast<unsigned long long>(a.seed), t.effects.names().c_str(), t.wall_s);
  std::printf(
      "Every parameter set is judged on the unit's table run (paper §VII). Legacy = the textbook "
      "multi-position method in the role of the paper's proprietary one.\n");
  print_factory_table(t, true);
  print_factory_table(t, false);
  print_field_table(t, PaperColumn::kLandAins, "III", "on land");
  print_field_table(t, PaperColumn::kSeaAins, "IV", "at sea");
  print_findings(f);
  return f.hold() ? 0 : 3;
}

}  // namespace imucal::tools::imucal
