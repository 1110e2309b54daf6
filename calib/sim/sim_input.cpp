#include "calib/sim/sim_input.hpp"

#include <memory>

namespace imucal::calib::sim {
using namespace calib::core;
using namespace calib::effects;

CalibrationInput input_from_simulation(const SimResult& sim, const TableGeometry& geometry,
                                       const Site& site, const NoiseModel& noise) {
  CalibrationInput in;
  in.site = site;
  in.imu = sim.imu;
  in.noise = noise;
  TableModel table(geometry);
  in.reference.reserve(sim.table.size());
  for (const auto& ts : sim.table)
    in.reference.push_back(
        {ts.t_s, table.C_bn(ts.outer_rad, ts.inner_rad), ts.at_rest, ts.outer_rad, ts.inner_rad});
  return in;
}

RunSource truth_run_source(const sequences::MotionProfile& profile, const TableGeometry& geometry,
                           const Site& site, const UnitModel& unit, double rate_hz) {
  auto world = std::make_shared<const sequences::MotionProfile>(profile);
  return [world, geometry, site, unit, rate_hz](const Effects& effects, uint64_t seed, bool noise) {
    UnitModel u = unit;
    u.effects = effects;
    SimOptions so;
    so.rate_hz = rate_hz;
    so.seed = seed;
    so.noise = noise;
    return input_from_simulation(simulate(*world, geometry, site, u, so), geometry, site,
                                 unit.noise);
  };
}

RunSource field_run_source(const sequences::MotionProfile& profile, const Site& site,
                           const UnitModel& unit, const FieldSimOptions& options, Grade grade) {
  auto world = std::make_shared<const sequences::MotionProfile>(profile);
  return [world, site, unit, options, grade](const Effects& effects, uint64_t seed, bool noise) {
    UnitModel u = unit;
    u.effects = effects;
    FieldSimOptions o = options;
    o.seed = seed;
    o.noise = noise;
    const FieldSimResult sim = simulate_field(*world, site, u, o);
    return input_from_field_data(o.setting, sim.imu, sim.gnss, site, unit.noise, grade);
  };
}

}  // namespace imucal::calib::sim
