#pragma once
// table_time_offset (ARCHITECTURE §7): the encoder log is stamped late (or early) against the IMU
// clock: the angles logged at IMU time t are the table's angles at t - δt. Only matters where
// encoder angles during motion are used (an angle error ω δt); at rest it is invisible.
namespace imucal::calib::effects {

/// The instant whose true table angles the encoder log shows at IMU time t.
inline double encoder_source_time_s(double t_imu_s, double offset_s) { return t_imu_s - offset_s; }

}  // namespace imucal::calib::effects
