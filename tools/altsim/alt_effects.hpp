#pragma once
// The effects catalogue's names and parameter orders, as altsim takes them on the command line
// (`--effect NAME=V1,V2,...`, SI values in the catalogue's order) and writes them to truth.json.
// altsim keeps its own table of them (it may not include the project's catalogue): the names
// and orders must match calib/effects/catalogue.cpp, which the tests check through the archive
// reader (truth.json is read strictly).
#include <string>
#include <vector>

#include "tools/altsim/alt_sim.hpp"

namespace imucal::tools::altsim {

struct AltEffectParams {
  std::string name;                 ///< catalogue name, e.g. "gyro_g_sensitivity"
  std::vector<std::string> params;  ///< parameter names in the catalogue's order
  /// The last parameter is a shape parameter (a time constant): optional on the command line,
  /// must be > 0, and does not make the effect active.
  bool trailing_shape = false;
};

/// Every effect altsim simulates (the catalogue's 15), in catalogue order.
const std::vector<AltEffectParams>& alt_effect_table();
/// "a, b, c" for error messages.
std::string alt_effect_names();

/// The effect's SI parameter vector (its table order) from `fx`.
std::vector<double> alt_effect_values(const AltEffects& fx, const std::string& name);
/// Whether any of the effect's non-shape parameters is non-zero.
bool alt_effect_active(const AltEffects& fx, const std::string& name);

/// Parses "NAME=V[,V...]" and sets the effect in fx (a trailing shape parameter may be left out:
/// it keeps its value). Throws std::invalid_argument naming the effect and its parameters.
void apply_alt_effect_spec(AltEffects& fx, const std::string& spec);

}  // namespace imucal::tools::altsim
