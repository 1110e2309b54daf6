#include "tools/imucal/effects_cmd.hpp"

#include <array>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <nlohmann/json.hpp>

#include "calib/diagnosis/diagnosis.hpp"
#include "calib/diagnosis/gap_fit.hpp"
#include "calib/effects/catalogue.hpp"

namespace imucal::tools::imucal {

namespace {

const char* kind_name(calib::effects::EffectKind k) {
  switch (k) {
    case calib::effects::EffectKind::kSensor:
      return "sensor";
    case calib::effects::EffectKind::kTable:
      return "table";
    case calib::effects::EffectKind::kSite:
      return "site";
    case calib::effects::EffectKind::kStochastic:
      return "stochastic";
  }
  return "?";
}

/// The largest size the diagnosis takes as plausible on a unit of each grade, in the magnitude's
/// unit (calib/diagnosis/gap_fit.hpp plausible_limit_typical at the default options): beyond it a
/// fitted size is an alias of another effect, never a finding (issue #49).
std::array<double, 3> plausible_max(const calib::effects::EffectInfo& e) {
  const double t = e.magnitude(Eigen::Map<const Eigen::VectorXd>(
      e.typical.data(), static_cast<Eigen::Index>(e.typical.size())));
  const double max_typical = calib::diagnosis::DiagnosisOptions{}.max_plausible_typical;
  std::array<double, 3> out{};
  for (auto g :
       {calib::core::Grade::kNavigation, calib::core::Grade::kTactical, calib::core::Grade::kMems})
    out[static_cast<size_t>(g)] = calib::diagnosis::plausible_limit_typical(e.id, g, max_typical) *
                                  (e.magnitude_params.empty() ? 1.0 : t);
  return out;
}

}  // namespace

int cmd_effects(bool json) {
  if (json) {
    nlohmann::json a = nlohmann::json::array();
    for (const auto& e : calib::effects::effect_catalogue()) {
      nlohmann::json ps = nlohmann::json::array();
      for (int i = 0; i < e.size(); ++i) {
        const auto& p = e.params[static_cast<size_t>(i)];
        ps.push_back({{"name", p.name},
                      {"si_unit", p.si_unit},
                      {"human_unit", p.human_unit},
                      {"si_to_human", p.si_to_human},
                      {"shape", p.shape},
                      {"typical_si", e.typical[static_cast<size_t>(i)]}});
      }
      a.push_back({{"name", e.name},
                   {"kind", kind_name(e.kind)},
                   {"model", e.model},
                   {"signature", e.signature},
                   {"parameters", ps},
                   {"magnitude_unit", e.magnitude_unit()},
                   {"plausible_max", plausible_max(e)}});
    }
    std::cout << a.dump(2) << '\n';
    return 0;
  }
  std::printf(
      "effects catalogue (ARCHITECTURE §7): inject with  imucal simulate|stationsim --effect "
      "NAME=V[,V...]\n"
      "(SI values in the order below; a trailing (shape) parameter may be left out)\n");
  for (const auto& e : calib::effects::effect_catalogue()) {
    std::printf("\n%s  [%s]\n  model:     %s\n  signature: %s\n  --effect %s=", e.name.c_str(),
                kind_name(e.kind), e.model.c_str(), e.signature.c_str(), e.name.c_str());
    for (int i = 0; i < e.size(); ++i)
      std::printf("%s%s", i ? "," : "", e.params[static_cast<size_t>(i)].name.c_str());
    std::printf("\n");
    for (int i = 0; i < e.size(); ++i) {
      const auto& p = e.params[static_cast<size_t>(i)];
      const double t = e.typical[static_cast<size_t>(i)];
      std::printf("    %-12s SI %-16s typical %-12.4g (%g %s)%s\n", p.name.c_str(),
                  p.si_unit.c_str(), t, t * p.si_to_human, p.human_unit.c_str(),
                  p.shape ? "  shape parameter" : "");
    }
    const std::array<double, 3> m = plausible_max(e);
    if (e.typical.empty() || !std::isfinite(m[0])) continue;
    std::printf("  plausible up to (diagnosis): navigation %.3g, tactical %.3g, MEMS %.3g %s\n",
                m[0], m[1], m[2], e.magnitude_unit().c_str());
  }
  return 0;
}

}  // namespace imucal::tools::imucal
