#pragma once
// The built-in IMU protocol's files compiled into the program (drivers/imu/protocols/
// imucal-imu-1.toml and drivers/imu/imu.dbc, byte for byte; generated at configure time by
// drivers/CMakeLists.txt), so that the default protocol never depends on a file being installed.
#include <string>

namespace imucal::drivers::imu {

std::string builtin_protocol_toml_text();
std::string builtin_protocol_dbc_text();

}  // namespace imucal::drivers::imu
