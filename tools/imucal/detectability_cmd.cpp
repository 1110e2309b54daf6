#include "tools/imucal/detectability_cmd.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <nlohmann/json.hpp>

#include "calib/core/site_presets.hpp"
#include "calib/diagnosis/diagnosis.hpp"
#include "calib/diagnosis/effect_detectability.hpp"
#include "calib/sim/sim_input.hpp"
#include "db/archive/unit_file.hpp"
#include "sequences/library.hpp"
#include "tools/imucal/format.hpp"

namespace imucal::tools::imucal {

namespace {

/// What would separate an effect that a sequence cannot: the physics of each catalogue effect's
/// signature (ARCHITECTURE §7). Shown next to the effects the analysis finds not separable.
std::string remedy(calib::effects::EffectId id) {
  using calib::effects::EffectId;
  switch (id) {
    case EffectId::kAccelQuadraticK2:
    case EffectId::kAccelAsymmetry:
      return "no gravity-only table sequence: with a free bias (and the odd part in the scale "
             "factor) K2 f^2 and Kap |f| correlate >= 0.96 for any set of static tilts within "
             "[0, 1] g (60 deg tilts take it from 0.998 to 0.96); telling them apart needs "
             "specific "
             "forces beyond 1 g (a centrifuge). The gap itself is found, as one of the two";
    case EffectId::kGravityError:
      return "no rotation sequence: the table offers no reference acceleration other than gravity, "
             "so a gravity error is a common accelerometer scale factor; survey the local gravity";
    case EffectId::kTableTimeOffset:
      return "none needed: the calibration uses encoder angles only at rest, so the offset cannot "
             "bias it; to measure it, log the encoder angles during motion at the IMU rate";
    case EffectId::kSizeEffect:
      return "faster rotations (the signature grows with w^2) about each body axis with the other "
             "axes horizontal";
    case EffectId::kGyroAccelSkew:
      return "faster rotations with gravity perpendicular to the rotation axis";
    case EffectId::kTableWobble:
    case EffectId::kTableNonorthogonality:
      return "longer rests (the gyros' Earth-rate sensing tells a leaning table axis from the "
             "gyro misalignments): e.g. factory-std instead of short";
    case EffectId::kThermalDrift:
      return "a run several warm-up time constants long with positions repeated early and late "
             "(on a short run the warm-up is a bias): e.g. factory-std instead of short";
    case EffectId::kLatitudeError:
      return "longer rests with each body axis north and down (gyrocompassing sees the Earth rate "
             "split)";
    default:
      return "longer rests";
  }
}

std::string joined(const std::vector<std::string>& names) {
  std::string s;
  for (const auto& n : names) s += (s.empty() ? "" : ", ") + n;
  return s;
}

/// A correlation as printed: three decimals (0.995, 1.000), enough to tell one just over the 0.95
/// limit from the limit, short enough to read in a table.
std::string correlation(double rho) { return fmt("%.3f", rho); }

/// Why an effect is not separable: the analysis' reason
/// (calib::diagnosis::EffectDetectability::reason) with its correlations to three digits; the
/// analysis writes them at full precision ("0.994933").
std::string reason_text(const calib::diagnosis::EffectDetectability& e) {
  // The limit effect_detectability applied: cmd_crlb_effects passes the default options.
  const double limit = calib::diagnosis::DiagnosisOptions{}.separability_limit;
  if (e.separable_directions == 0 && e.no_signature < e.directions && !e.aliases.empty())
    return "correlates " + correlation(std::max(e.max_correlation, limit)) + " > " +
           fmt("%.2f", limit) + " with the base parameters (" + joined(e.aliases) + ")";
  if (e.separable_directions > 0 && !e.confounded_with.empty())
    return "confounded with " + joined(e.confounded_with) + " (signatures correlate " +
           correlation(e.max_cross_correlation) + " > " + fmt("%.2f", limit) + ")";
  return e.reason;
}

/// threshold / typical: how many times its catalogue typical size an effect must be to be named
/// about half the time; NaN where there is no threshold or no typical size.
double ratio_to_typical(const calib::diagnosis::EffectDetectability& e) {
  return std::isfinite(e.threshold) && e.typical > 0 ? e.threshold / e.typical : std::nan("");
}

/// Separated from everything else on this sequence, yet at its typical size below the detection
/// threshold: a real unit's effect of this kind would go unnoticed.
bool separable_but_too_small(const calib::diagnosis::EffectDetectability& e) {
  return e.separable() && ratio_to_typical(e) > 1.0;
}

void print_rows(const std::vector<calib::diagnosis::EffectDetectability>& d) {
  std::printf("  %-24s %-11s %15s %15s  %-6s  %s\n", "effect", "directions", "threshold", "typical",
              "ratio", "separable?");
  for (const auto& e : d) {
    char thr[32] = "-", typ[32] = "-", ratio[16] = "-";
    if (std::isfinite(e.threshold))
      std::snprintf(thr, sizeof thr, "%.3g %s", e.threshold, e.unit.c_str());
    if (std::isfinite(ratio_to_typical(e)))
      std::snprintf(ratio, sizeof ratio, "%.2g", ratio_to_typical(e));
    if (e.typical > 0) std::snprintf(typ, sizeof typ, "%.3g %s", e.typical, e.unit.c_str());
    char dirs[16];
    std::snprintf(dirs, sizeof dirs, "%d of %d", e.separable_directions, e.directions);
    const std::string sep = !e.separable()               ? "no: " + reason_text(e)
                            : separable_but_too_small(e) ? "yes, not at typical size"
                                                         : "yes";
    std::printf("  %-24s %-11s %15s %15s  %-6s  %s\n", e.name.c_str(), dirs, thr, typ, ratio,
                sep.c_str());
  }
}

void print_too_small(const std::vector<calib::diagnosis::EffectDetectability>& d) {
  bool any = false;
  for (const auto& e : d) {
    if (!separable_but_too_small(e)) continue;
    if (!any) std::printf("\nseparable but not detectable at its typical size on this sequence:\n");
    any = true;
    std::printf(
        "  %-24s at its typical size (%.3g %s) it is below the detection threshold: it must "
        "be %.2gx that (%.3g %s) to be named about half the time\n",
        e.name.c_str(), e.typical, e.unit.c_str(), ratio_to_typical(e), e.threshold,
        e.unit.c_str());
  }
}

void print_table(const std::vector<calib::diagnosis::EffectDetectability>& d,
                 const std::string& seq, double false_alarm) {
  std::printf(
      "effects on sequence %s: detection threshold (the diagnosis names an effect of this size "
      "about half the time; 3x it essentially always) and separability, at a false-alarm rate of "
      "%.3g per run%s\n",
      seq.c_str(), false_alarm,
      false_alarm == calib::diagnosis::kDefaultGapFalseAlarm
          ? " (the station's default gap_false_alarm)"
          : "");
  std::printf(
      "ratio = threshold / typical: how many times its catalogue typical size an effect must be "
      "to be detected (above 1: not detectable at its typical size on this sequence)\n");
  print_rows(d);
  print_too_small(d);
  bool any = false;
  for (const auto& e : d)
    if (!e.separable() && e.id != calib::effects::EffectId::kBiasInstability &&
        e.id != calib::effects::EffectId::kQuantisation &&
        e.id != calib::effects::EffectId::kOutputFilter &&
        e.id != calib::effects::EffectId::kRestTremor) {
      if (!any) std::printf("\nto separate what this sequence cannot:\n");
      any = true;
      std::printf("  %-24s %s\n", e.name.c_str(), remedy(e.id).c_str());
    }
}

nlohmann::json to_json(const std::vector<calib::diagnosis::EffectDetectability>& d,
                       const std::string& seq) {
  nlohmann::json a = nlohmann::json::array();
  for (const auto& e : d) {
    const double ratio = ratio_to_typical(e);
    nlohmann::json j = {
        {"effect", e.name},
        {"directions", e.directions},
        {"separable_directions", e.separable_directions},
        {"no_signature", e.no_signature},
        {"max_correlation", e.max_correlation},
        {"max_cross_correlation", e.max_cross_correlation},
        {"aliases", e.aliases},
        {"confounded_with", e.confounded_with},
        {"threshold",
         std::isfinite(e.threshold) ? nlohmann::json(e.threshold) : nlohmann::json(nullptr)},
        {"typical", e.typical},
        {"unit", e.unit},
        {"ratio", std::isfinite(ratio) ? nlohmann::json(ratio) : nlohmann::json(nullptr)},
        {"detectable_at_typical", std::isfinite(ratio) && ratio <= 1.0},
        {"separable", e.separable()},
        {"reason", reason_text(e)}};
    if (!e.separable()) j["remedy"] = remedy(e.id);
    a.push_back(j);
  }
  return {{"sequence", seq}, {"effects", a}};
}

}  // namespace

int cmd_crlb_effects(const std::string& seq, const std::string& unit_path, double rate_hz,
                     double false_alarm, bool json) {
  const std::string seq_path = sequences::resolve_sequence(seq);
  const sequences::MotionProfile profile = sequences::load_profile(seq_path);
  const calib::effects::UnitModel unit =
      unit_path.empty() ? calib::effects::default_unit() : db::archive::read_unit_file(unit_path);
  const calib::effects::RunSource world = calib::sim::truth_run_source(
      profile, calib::core::TableGeometry{}, calib::core::demo_factory_site(), unit, rate_hz);
  const auto d = calib::diagnosis::effect_detectability(
      world(calib::effects::Effects{}, 1, /*noise=*/false), calib::core::TableGeometry{},
      unit.params, calib::diagnosis::diagnosis_options_for_false_alarm(false_alarm));
  if (json) {
    nlohmann::json j = to_json(d, profile.name);
    j["false_alarm_per_run"] = false_alarm;
    std::cout << j.dump(2) << '\n';
  } else {
    print_table(d, profile.name, false_alarm);
  }
  return 0;
}

}  // namespace imucal::tools::imucal
