#pragma once
// altsim (tools/altsim/, issue #22) as a calib::effects::RunSource: the same contract as
// calib::sim::truth_run_source (calib/sim/sim_input.hpp) — runs of one sequence on one table by one
// unit with chosen effects, the reference attitude from the recorded encoder angles, the unit's
// declared noise model — but drawn from the independent simulator, so that `imucal
// validate-diagnosis --simulator alt` measures the diagnosis on data its own world did not make.
// The conversions from the project's types to altsim's plain structs are exposed for the tests.
#include "calib/core/calibration_input.hpp"
#include "calib/core/table_model.hpp"
#include "calib/effects/run_source.hpp"
#include "calib/sim/truth_sim.hpp"
#include "sequences/motion_profile.hpp"
#include "tools/altsim/alt_sim.hpp"

namespace imucal::tools::imucal {

/// The catalogue's effects in altsim's struct (field by field, same SI definitions).
tools::altsim::AltEffects to_alt_effects(const calib::effects::Effects& fx);
/// The unit's parameters, declared noise and effects.
tools::altsim::AltUnit to_alt_unit(const calib::effects::UnitModel& unit);
/// The table geometry with the station's misalignment ς (the unit's table_misalignment_rad).
tools::altsim::AltTable to_alt_table(const calib::core::TableGeometry& geometry,
                                     const Eigen::Vector3d& sigma);
/// The configured site. Without a surveyed gravity the physics has normal gravity at the TRUE
/// latitude (calib/effects/site_errors.hpp), so that value is passed (altsim adds dg on top).
tools::altsim::AltSite to_alt_site(const calib::core::Site& site,
                                   const calib::effects::Effects& fx);

/// What the methods consume from an altsim run: the increments, the table reference
/// C_bn_ref = TableModel(geometry).C_bn(encoder angles) without ς, the rest flags, the declared
/// noise model, the configured site.
calib::core::CalibrationInput input_from_alt(const std::vector<tools::altsim::AltSample>& run,
                                             const calib::core::TableGeometry& geometry,
                                             const calib::core::Site& site,
                                             const calib::core::NoiseModel& noise);

/// altsim as a RunSource (callable from several threads at once: every call simulates into its
/// own storage; the profile is shared read-only).
calib::effects::RunSource alt_run_source(const sequences::MotionProfile& profile,
                                         const calib::core::TableGeometry& geometry,
                                         const calib::core::Site& site,
                                         const calib::effects::UnitModel& unit, double rate_hz);

}  // namespace imucal::tools::imucal
