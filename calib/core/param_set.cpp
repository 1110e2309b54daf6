#include "calib/core/param_set.hpp"

#include "calib/core/conventions.hpp"

namespace imucal::calib::core {

ParamVector ParamSet::to_vector() const {
  ParamVector x;
  x.segment<3>(0) = accel_bias_mps2;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) x(3 + 3 * r + c) = accel_M(r, c);
  x.segment<3>(12) = gyro_bias_radps;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) x(15 + 3 * r + c) = gyro_M(r, c);
  x.segment<3>(24) = table_misalignment_rad;
  return x;
}

ParamSet ParamSet::from_vector(const ParamVector& x) {
  ParamSet p;
  p.accel_bias_mps2 = x.segment<3>(0);
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) p.accel_M(r, c) = x(3 + 3 * r + c);
  p.gyro_bias_radps = x.segment<3>(12);
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) p.gyro_M(r, c) = x(15 + 3 * r + c);
  p.table_misalignment_rad = x.segment<3>(24);
  return p;
}

namespace {
std::vector<ParamInfo> make_infos() {
  std::vector<ParamInfo> v;
  auto idx = [](int i) { return "[" + std::to_string(i) + "]"; };
  for (int i = 0; i < 3; ++i)
    v.push_back({"accel_bias_mps2" + idx(i), ParamGroup::kAccelBias, "µg", 1.0 / kMicroG_mps2});
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c)
      v.push_back({"accel_M" + idx(r) + idx(c),
                   r == c ? ParamGroup::kAccelScale : ParamGroup::kAccelMisalign,
                   r == c ? "ppm" : "µrad", 1e6});
  for (int i = 0; i < 3; ++i)
    v.push_back(
        {"gyro_bias_radps" + idx(i), ParamGroup::kGyroBias, "deg/h", 1.0 / kDegPerHourToRadPerSec});
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c)
      v.push_back({"gyro_M" + idx(r) + idx(c),
                   r == c ? ParamGroup::kGyroScale : ParamGroup::kGyroMisalign,
                   r == c ? "ppm" : "µrad", 1e6});
  for (int i = 0; i < 3; ++i)
    v.push_back({"table_misalignment_rad" + idx(i), ParamGroup::kTableMisalign, "arcsec",
                 1.0 / kArcsecToRad});
  return v;
}
}  // namespace

const ParamInfo& param_info(int i) {
  static const std::vector<ParamInfo> infos = make_infos();
  return infos.at(static_cast<size_t>(i));
}

std::string group_name(ParamGroup g) {
  switch (g) {
    case ParamGroup::kAccelBias:
      return "accel_bias";
    case ParamGroup::kAccelScale:
      return "accel_scale";
    case ParamGroup::kAccelMisalign:
      return "accel_misalignment";
    case ParamGroup::kGyroBias:
      return "gyro_bias";
    case ParamGroup::kGyroScale:
      return "gyro_scale";
    case ParamGroup::kGyroMisalign:
      return "gyro_misalignment";
    case ParamGroup::kTableMisalign:
      return "table_misalignment";
  }
  return "?";
}

}  // namespace imucal::calib::core
