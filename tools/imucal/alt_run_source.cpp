#include "tools/imucal/alt_run_source.hpp"

#include <cmath>
#include <limits>
#include <memory>

#include "calib/core/earth.hpp"

namespace imucal::tools::imucal {

tools::altsim::AltEffects to_alt_effects(const calib::effects::Effects& fx) {
  tools::altsim::AltEffects a;
  a.accel_k2_per_mps2 = fx.accel_k2_per_mps2;
  a.accel_asym = fx.accel_asym;
  a.accel_lever_arm_m = fx.accel_lever_arm_m;
  a.gyro_g_sens = fx.gyro_g_sens;
  a.gyro_accel_skew_s = fx.gyro_accel_skew_s;
  a.thermal_accel_mps2 = fx.thermal_accel_mps2;
  a.thermal_gyro_radps = fx.thermal_gyro_radps;
  a.thermal_tau_s = fx.thermal_tau_s;
  a.instability_gyro_radps = fx.instability_gyro_radps;
  a.instability_accel_mps2 = fx.instability_accel_mps2;
  a.instability_tau_s = fx.instability_tau_s;
  a.quant_dtheta_rad = fx.quant_dtheta_rad;
  a.quant_dv_mps = fx.quant_dv_mps;
  a.output_filter_gyro = fx.output_filter_gyro;
  a.output_filter_accel = fx.output_filter_accel;
  a.tremor_rate_rms_radps = fx.tremor_rate_rms_radps;
  a.tremor_tilt_rms_rad = fx.tremor_tilt_rms_rad;
  a.tremor_pivot_m = fx.tremor_pivot_m;
  a.table_time_offset_s = fx.table_time_offset_s;
  a.table_nonorthogonality_rad = fx.table_nonorthogonality_rad;
  a.table_wobble_rad = fx.table_wobble_rad;
  a.gravity_error_mps2 = fx.gravity_error_mps2;
  a.latitude_error_rad = fx.latitude_error_rad;
  return a;
}

tools::altsim::AltUnit to_alt_unit(const calib::effects::UnitModel& unit) {
  tools::altsim::AltUnit u;
  u.errors.b_a_mps2 = unit.params.accel_bias_mps2;
  u.errors.M_a = unit.params.accel_M;
  u.errors.b_g_radps = unit.params.gyro_bias_radps;
  u.errors.M_g = unit.params.gyro_M;
  const calib::core::NoiseModel& n = unit.noise;
  u.noise.arw_rad_per_sqrt_s = n.arw_rad_per_sqrt_s;
  u.noise.vrw_mps_per_sqrt_s = n.vrw_mps_per_sqrt_s;
  u.noise.gyro_gm_sigma_radps = n.gyro_bias_instability_radps;
  u.noise.gyro_gm_tau_s = n.gyro_bias_tau_s;
  u.noise.accel_gm_sigma_mps2 = n.accel_bias_instability_mps2;
  u.noise.accel_gm_tau_s = n.accel_bias_tau_s;
  u.noise.dtheta_lsb_rad = n.dtheta_lsb_rad;
  u.noise.dv_lsb_mps = n.dv_lsb_mps;
  u.effects = to_alt_effects(unit.effects);
  return u;
}

tools::altsim::AltTable to_alt_table(const calib::core::TableGeometry& g,
                                     const Eigen::Vector3d& sigma) {
  tools::altsim::AltTable t;
  t.outer_axis_t = g.outer_axis_t;
  t.inner_axis_o = g.inner_axis_o;
  t.heading_rad = g.heading_rad;
  t.C_bp = g.C_bp;
  t.misalignment_rad = sigma;
  return t;
}

tools::altsim::AltSite to_alt_site(const calib::core::Site& site,
                                   const calib::effects::Effects& fx) {
  tools::altsim::AltSite s;
  s.lat_rad = site.lat_rad;
  s.gravity_mps2 = site.gravity_mps2 ? *site.gravity_mps2
                                     : calib::core::EarthModel::normal_gravity_mps2(
                                           site.lat_rad + fx.latitude_error_rad, site.height_m);
  s.earth_rate_radps = calib::core::wgs84::kEarthRate_radps;
  return s;
}

calib::core::CalibrationInput input_from_alt(const std::vector<tools::altsim::AltSample>& run,
                                             const calib::core::TableGeometry& geometry,
                                             const calib::core::Site& site,
                                             const calib::core::NoiseModel& noise) {
  calib::core::CalibrationInput in;
  in.site = site;
  in.noise = noise;
  in.imu.reserve(run.size());
  in.reference.reserve(run.size());
  const calib::core::TableModel table(geometry);
  for (const tools::altsim::AltSample& s : run) {
    calib::core::ImuIncrement inc;
    inc.t_s = s.t_s;
    inc.dt_s = s.dt_s;
    inc.dtheta_rad = s.dtheta_rad;
    inc.dv_mps = s.dv_mps;
    inc.temp_c = std::numeric_limits<double>::quiet_NaN();  // altsim models no temperature
    in.imu.push_back(inc);
    // The encoder's degrees as the archive reader converts them.
    const double outer_rad = s.outer_deg * kDegToRad, inner_rad = s.inner_deg * kDegToRad;
    in.reference.push_back(
        {s.t_s, table.C_bn(outer_rad, inner_rad), s.at_rest, outer_rad, inner_rad});
  }
  return in;
}

calib::effects::RunSource alt_run_source(const sequences::MotionProfile& profile,
                                         const calib::core::TableGeometry& geometry,
                                         const calib::core::Site& site,
                                         const calib::effects::UnitModel& unit, double rate_hz) {
  auto world = std::make_shared<const sequences::MotionProfile>(profile);
  return [world, geometry, site, unit, rate_hz](const calib::effects::Effects& effects,
                                                uint64_t seed, bool noise) {
    calib::effects::UnitModel u = unit;
    u.effects = effects;
    tools::altsim::AltOptions o;
    o.rate_hz = rate_hz;
    o.seed = seed;
    o.noise = noise;
    o.rest_guard_s = calib::core::kTableRestGuard_s;
    const std::vector<tools::altsim::AltSample> run =
        tools::altsim::simulate_alt(*world, to_alt_table(geometry, u.params.table_misalignment_rad),
                                    to_alt_site(site, effects), to_alt_unit(u), o);
    return input_from_alt(run, geometry, site, unit.noise);
  };
}

}  // namespace imucal::tools::imucal
