#pragma once
// `imucal effects [--json]`: the effects catalogue (calib/effects/catalogue.hpp, ARCHITECTURE §7)
// as test engineers read it — each effect's name (as unit files, truth.json, --effect and reports
// use it), its model, its signature, and its parameters with SI and human units and a typical
// navigation-grade value.
namespace imucal::tools::imucal {

int cmd_effects(bool json);

}  // namespace imucal::tools::imucal
