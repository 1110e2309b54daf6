#include "calib/sim/sim_input.hpp"

namespace imucal::calib {

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

}  // namespace imucal::calib
