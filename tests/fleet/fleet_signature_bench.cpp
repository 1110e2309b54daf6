// Benchmark (not a test): build/bin/fleet_signature_bench [--fleets N] [--units N] [--all-errors]:
// issue #25's figures. N simulated fleets (default 20) of 10 stations × 50 units of a production
// population (calib/sim/unit_draw.hpp) plus one golden-unit visit per station, the real simulator
// and AINS on `short`, tables levelled within ±20″; in fleet f the station f mod 10 has a 50 µg
// gravity error and (f + 5) mod 10 a 10″ table non-orthogonality (the fleet); with
// --all-errors also (f + 2) mod 10 a fixture turned 60″ about the platform axis f mod 3, (f + 7)
// mod 10 a table wobbling 10″ about axis f mod 2 and (f + 4) mod 10 both a 50 µg gravity error and
// a 10″ non-orthogonality. Prints, over all fleets:
//   * detection (faulty stations with every error named and no other, per kind) and false alarms
//     (sound stations flagged), with the golden unit and with units alone, each with its exact 95 %
//     interval;
//   * the gravity station's runs reprocessed with the fitted correction and with the exact one (a
//     re-survey): (accelerometer scale - truth) / σ, against the run's σ and, for the fitted
//     correction, against the run's σ combined with the correction's own;
//   * the smallest station error detectable with N units (95 % power at the threshold): from the
//     fitted sizes' σ on the fleets' first N units per station, with and without the golden unit.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <string>

#include "calib/core/binomial_interval.hpp"
#include "calib/core/conventions.hpp"
#include "tools/fleetsim/fleet_sim.hpp"

namespace {

using namespace imucal;
using namespace imucal::calib;
using namespace imucal::calib::core;
using namespace imucal::calib::studies::fleet;
using namespace imucal::tools::fleetsim;

/// k of n with its exact (Clopper-Pearson) 95 % interval: k is often 0 or 1 here.
void rate(const char* what, int k, int n) {
  const RateInterval ci = clopper_pearson(k, std::max(1, n));
  const double lo = ci.lower, hi = ci.upper;
  std::printf("  %-44s %4d / %-4d = %6.2f %%  (95 %%: %.2f – %.2f %%)\n", what, k, n,
              100.0 * k / std::max(1, n), 100 * lo, 100 * hi);
}

/// The station error's kind, for per-cause rates: "fixture_rotation_y" -> "fixture rotation".
std::string kind_of(const std::string& cause) {
  if (cause.rfind("fixture_rotation_", 0) == 0) return "fixture rotation";
  if (cause.rfind("table_wobble_", 0) == 0) return "table wobble";
  return cause == "gravity_error" ? "gravity error" : "table non-orthogonality";
}

struct Totals {
  int faulty = 0, detected = 0, wrong = 0, sound = 0, false_alarms = 0;
  std::map<std::string, std::pair<int, int>> by_kind;  ///< kind -> (detected, faulty)
  void add(const FleetSpec& spec, const FleetOutcome& o) {
    faulty += o.faulty, detected += o.detected, wrong += o.wrong_cause;
    sound += o.sound, false_alarms += o.false_alarms;
    for (std::size_t s = 0; s < spec.stations.size(); ++s) {
      std::vector<std::string> causes = true_causes(spec.stations[s]);
      if (causes.empty()) continue;
      const std::string kind =
          causes.size() == 1 ? kind_of(causes[0]) : "two at once (gravity + non-orthogonality)";
      auto& [k, n] = by_kind[kind];
      std::vector<std::string> named;
      for (const StationFit& a : o.signatures.stations[s].alarms) named.push_back(a.effect);
      std::sort(causes.begin(), causes.end());
      std::sort(named.begin(), named.end());
      k += named == causes ? 1 : 0;  // every error named, nothing else
      ++n;
    }
  }
  void print() const {
    rate("faulty stations, every error named, no other", detected, faulty);
    for (const auto& [kind, kn] : by_kind) rate(("  " + kind).c_str(), kn.first, kn.second);
    rate("faulty stations named an error they lack", wrong, faulty);
    rate("sound stations flagged (false alarms)", false_alarms, sound);
  }
};

FleetSpec fleet(int f, int units, bool all_errors) {
  FleetSpec spec = sound_fleet(10, 20.0 * kArcsecToRad, 1000 + static_cast<std::uint64_t>(f));
  spec.units_per_station = units;
  spec.stations[static_cast<std::size_t>(f % 10)].gravity_error_mps2 = 50.0 * kMicroG_mps2;
  spec.stations[static_cast<std::size_t>((f + 5) % 10)].nonorthogonality_rad = 10.0 * kArcsecToRad;
  if (all_errors) {
    spec.stations[static_cast<std::size_t>((f + 2) % 10)].fixture_rad =
        60.0 * kArcsecToRad * Eigen::Vector3d::Unit(f % 3);
    spec.stations[static_cast<std::size_t>((f + 7) % 10)].wobble_rad =
        10.0 * kArcsecToRad * Eigen::Vector2d::Unit(f % 2);
    StationSpec& both = spec.stations[static_cast<std::size_t>((f + 4) % 10)];
    both.gravity_error_mps2 = 50.0 * kMicroG_mps2;
    both.nonorthogonality_rad = 10.0 * kArcsecToRad;
  }
  return spec;
}

/// The runs of the first `n` units per station (and the golden unit's, if `golden`).
std::vector<FleetRun> first_units(const std::vector<FleetRun>& runs, int n, bool golden) {
  std::vector<FleetRun> out;
  for (const FleetRun& r : runs)
    if (r.unit < 0 ? golden : r.unit < n) out.push_back(r);
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  int fleets = 20, units = 50;
  bool all_errors = false;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--all-errors")) all_errors = true;
    if (i + 1 >= argc) continue;
    if (!std::strcmp(argv[i], "--fleets")) fleets = std::atoi(argv[i + 1]);
    if (!std::strcmp(argv[i], "--units")) units = std::atoi(argv[i + 1]);
  }
  const auto t0 = std::chrono::steady_clock::now();
  const std::vector<StationError> errors = fleet_station_errors(fleet(0, units, all_errors));
  const SignatureOptions options;
  const double z_thr = bonferroni_z(options.false_alarm, static_cast<int>(errors.size()));
  std::printf(
      "%d fleets of 10 stations x %d units + 1 golden visit each, on short; threshold "
      "|z| >= %.2f (false alarms %.3g per station and period)\n",
      fleets, units, z_thr, options.false_alarm);
  Totals golden, alone;
  int within = 0, within_both = 0, within_exact = 0, reprocessed = 0;
  double sum_z2 = 0, sum_z2_both = 0, sum_z2_exact = 0, worst_after = 0, worst_both = 0,
         worst_exact = 0, best_before = 1e9;
  const std::vector<int> ns = {5, 10, 20, 50};
  // Per N, kind and golden (0/1): the sum of squared σ of the fitted sizes on sound stations
  // (a kind's axes averaged) and the count of stations.
  std::vector<std::map<std::string, std::array<double, 2>>> sigma2(ns.size());
  std::vector<int> count(ns.size(), 0);
  std::vector<std::string> kinds;  // catalogue order
  std::map<std::string, const StationError*> first_of_kind;
  for (const StationError& e : errors)
    if (first_of_kind.emplace(kind_of(e.effect), &e).second) kinds.push_back(kind_of(e.effect));
  for (int f = 0; f < fleets; ++f) {
    const FleetSpec spec = fleet(f, units, all_errors);
    const std::vector<FleetRun> runs = simulate_fleet(spec);
    const FleetOutcome og = assess_fleet(spec, runs, errors, options, false);
    const FleetOutcome oa = assess_fleet(spec, runs, errors, options, true);
    golden.add(spec, og);
    alone.add(spec, oa);
    const std::size_t gs = static_cast<std::size_t>(f % 10);
    const auto& alarm = og.signatures.stations[gs].alarm;
    if (alarm && alarm->effect == "gravity_error") {
      // The fitted correction carries its own σ, common to the station's units: a scale corrected
      // with it is uncertain by the run's σ and the correction's (dg/g) together.
      const double fit_sigma_scale = alarm->sigma_si / kStandardGravity_mps2;
      const auto after = reprocess_with_gravity(spec, gs, alarm->size_si);
      const auto exact = reprocess_with_gravity(spec, gs, spec.stations[gs].gravity_error_mps2);
      const auto before = reprocess_with_gravity(spec, gs, 0.0);
      for (std::size_t i = 0; i < after.size(); ++i) {
        const double z = after[i].z(), z_exact = exact[i].z();
        const double z_both = after[i].error / std::hypot(after[i].sigma, fit_sigma_scale);
        within += std::abs(z) < 4.0 ? 1 : 0;
        within_both += std::abs(z_both) < 4.0 ? 1 : 0;
        within_exact += std::abs(z_exact) < 4.0 ? 1 : 0;
        ++reprocessed;
        sum_z2 += z * z, sum_z2_both += z_both * z_both, sum_z2_exact += z_exact * z_exact;
        worst_after = std::max(worst_after, std::abs(z));
        worst_both = std::max(worst_both, std::abs(z_both));
        worst_exact = std::max(worst_exact, std::abs(z_exact));
        best_before = std::min(best_before, before[i].z());
      }
    }
    for (std::size_t k = 0; k < ns.size(); ++k) {
      if (ns[k] > units) continue;
      for (int with_golden = 0; with_golden < 2; ++with_golden) {
        const FleetOutcome o =
            assess_fleet(spec, first_units(runs, ns[k], with_golden != 0), errors, options, false);
        for (std::size_t s = 0; s < spec.stations.size(); ++s) {
          if (!true_causes(spec.stations[s]).empty()) continue;
          const auto& fits = o.signatures.stations[s].fits;
          std::map<std::string, int> axes;
          for (const StationFit& fit : fits) ++axes[kind_of(fit.effect)];
          for (const StationFit& fit : fits)
            sigma2[k][kind_of(fit.effect)][static_cast<std::size_t>(with_golden)] +=
                fit.sigma_si * fit.sigma_si / axes[kind_of(fit.effect)];
          if (with_golden) ++count[k];
        }
      }
    }
    std::fprintf(stderr, "fleet %d/%d: golden %d/%d detected, %d false; alone %d/%d, %d false\n",
                 f + 1, fleets, og.detected, og.faulty, og.false_alarms, oa.detected, oa.faulty,
                 oa.false_alarms);
  }
  std::printf("\nwith the golden unit:\n");
  golden.print();
  std::printf("units alone (the golden unit's runs left out):\n");
  alone.print();
  const auto rms = [&](double sum) { return std::sqrt(sum / std::max(1, reprocessed)); };
  std::printf(
      "\nreprocessing the gravity station's runs (%d accelerometer scales; as stored the smallest "
      "(scale - truth)/σ was %.1f):\n",
      reprocessed, best_before);
  std::printf(
      "  with the fitted correction, against the run's σ:             within ±4σ %d, rms %.2f, "
      "largest %.2f\n",
      within, rms(sum_z2), worst_after);
  std::printf(
      "  with the fitted correction, against σ and the correction's σ: within ±4σ %d, rms "
      "%.2f, largest %.2f\n",
      within_both, rms(sum_z2_both), worst_both);
  std::printf(
      "  with the exact correction (a re-survey), against the run's σ: within ±4σ %d, rms "
      "%.2f, largest %.2f\n",
      within_exact, rms(sum_z2_exact), worst_exact);
  std::printf("\nsmallest station error detectable (95 %% power at |z| >= %.2f: (z + 1.645) σ):\n",
              z_thr);
  std::printf("  %-6s", "units");
  for (const std::string& kind : kinds) std::printf(" | %-36s", kind.c_str());
  std::printf("\n  %-6s", "");
  for (std::size_t i = 0; i < kinds.size(); ++i) std::printf(" | %-17s %-18s", "alone", "+ golden");
  std::printf("\n");
  for (std::size_t k = 0; k < ns.size(); ++k) {
    if (count[k] == 0) continue;
    std::printf("  %-6d", ns[k]);
    for (const std::string& kind : kinds) {
      const StationError& e = *first_of_kind.at(kind);
      for (std::size_t g = 0; g < 2; ++g) {
        const double size = (z_thr + 1.645) * std::sqrt(sigma2[k][kind][g] / count[k]);
        char cell[64];
        std::snprintf(cell, sizeof cell, "%.3g %s", size * e.si_to_human, e.unit.c_str());
        std::printf(g == 0 ? " | %-17s" : " %-18s", cell);
      }
    }
    std::printf("\n");
  }
  std::printf("\n%.0f s\n",
              std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  return 0;
}
