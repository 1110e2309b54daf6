#include "tools/imucal/detectability_cmd.hpp"

#include <cmath>
#include <cstdio>
#include <iostream>
#include <nlohmann/json.hpp>

#include "calib/effect_detectability.hpp"
#include "calib/site_presets.hpp"
#include "db/archive/unit_file.hpp"
#include "sequences/library.hpp"

namespace imucal::tools {

namespace {

/// What would separate an effect that a sequence cannot: the physics of each catalogue effect's
/// signature (DESIGN §7). Shown next to the effects the analysis finds not separable.
std::string remedy(calib::EffectId id) {
  using calib::EffectId;
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

void print_table(const std::vector<calib::EffectDetectability>& d, const std::string& seq) {
  std::printf(
      "effects on sequence %s: detection threshold (the diagnosis names an effect of this size "
      "about half the time; 3x it essentially always) and separability\n",
      seq.c_str());
  std::printf("  %-24s %-11s %14s %14s  %-6s  %s\n", "effect", "directions", "threshold", "typical",
              "ratio", "separable?");
  for (const auto& e : d) {
    char thr[32] = "-", typ[32] = "-", ratio[16] = "-";
    if (std::isfinite(e.threshold)) {
      std::snprintf(thr, sizeof thr, "%.3g %s", e.threshold, e.unit.c_str());
      if (e.typical > 0) std::snprintf(ratio, sizeof ratio, "%.2g", e.threshold / e.typical);
    }
    if (e.typical > 0) std::snprintf(typ, sizeof typ, "%.3g %s", e.typical, e.unit.c_str());
    char dirs[16];
    std::snprintf(dirs, sizeof dirs, "%d of %d", e.separable_directions, e.directions);
    std::printf("  %-24s %-11s %14s %14s  %-6s  %s\n", e.name.c_str(), dirs, thr, typ, ratio,
                e.separable() ? "yes" : ("no: " + e.reason).c_str());
  }
  bool any = false;
  for (const auto& e : d)
    if (!e.separable() && e.id != calib::EffectId::kBiasInstability &&
        e.id != calib::EffectId::kQuantisation) {
      if (!any) std::printf("\nto separate what this sequence cannot:\n");
      any = true;
      std::printf("  %-24s %s\n", e.name.c_str(), remedy(e.id).c_str());
    }
}

nlohmann::json to_json(const std::vector<calib::EffectDetectability>& d, const std::string& seq) {
  nlohmann::json a = nlohmann::json::array();
  for (const auto& e : d) {
    nlohmann::json j = {{"effect", e.name},
                        {"directions", e.directions},
                        {"separable_directions", e.separable_directions},
                        {"no_signature", e.no_signature},
                        {"max_correlation", e.max_correlation},
                        {"aliases", e.aliases},
                        {"confounded_with", e.confounded_with},
                        {"threshold", std::isfinite(e.threshold) ? nlohmann::json(e.threshold)
                                                                 : nlohmann::json(nullptr)},
                        {"typical", e.typical},
                        {"unit", e.unit},
                        {"separable", e.separable()},
                        {"reason", e.reason}};
    if (!e.separable()) j["remedy"] = remedy(e.id);
    a.push_back(j);
  }
  return {{"sequence", seq}, {"effects", a}};
}

}  // namespace

int cmd_crlb_effects(const std::string& seq, const std::string& unit_path, double rate_hz,
                     bool json) {
  const std::string seq_path = sequences::resolve_sequence(seq);
  const sequences::MotionProfile profile = sequences::load_profile(seq_path);
  const calib::UnitModel unit =
      unit_path.empty() ? calib::default_unit() : archive::read_unit_file(unit_path);
  const auto d = calib::effect_detectability(profile, calib::TableGeometry{},
                                             calib::demo_factory_site(), unit, rate_hz);
  if (json)
    std::cout << to_json(d, profile.name).dump(2) << '\n';
  else
    print_table(d, profile.name);
  return 0;
}

}  // namespace imucal::tools
