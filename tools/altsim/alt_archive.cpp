#include "tools/altsim/alt_archive.hpp"

#include <stdlib.h>

#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>
#include <system_error>

#include "tools/altsim/alt_effects.hpp"

namespace fs = std::filesystem;

namespace imucal::tools::altsim {

namespace {

/// Shortest decimal text that reads back to the same double (the archive reader uses from_chars).
void append_number(std::string& out, double x) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, x);
  out.append(buf, r.ptr);
}

/// A TOML float: the shortest text, with ".0" where it would otherwise read as an integer.
std::string toml_float(double x) {
  std::string s;
  append_number(s, x);
  if (s.find_first_of(".eE") == std::string::npos) s += ".0";
  return s;
}

std::string toml_vec3(const Eigen::Vector3d& v) {
  return "[" + toml_float(v.x()) + ", " + toml_float(v.y()) + ", " + toml_float(v.z()) + "]";
}

std::string run_toml(const AltRunInfo& i) {
  const AltNoise& n = i.unit.noise;
  const double arw_deg_per_sqrt_h = n.arw_rad_per_sqrt_s * (180.0 / kPi) * 60.0;
  const double vrw_ug_per_sqrt_hz = n.vrw_mps_per_sqrt_s / 9.80665e-6;
  std::ostringstream t;
  t << "# Run archive metadata (db/archive/FORMAT.md), written by altsim (tools/altsim): an\n"
    << "# independent simulator of the factory table run.\n"
    << "serial = \"" << i.serial << "\"\n"
    << "software_version = \"" << i.software_version << "\"\n"
    << "reference = \"table\"\n\n"
    << "[station]\nname = \"altsim\"\n"
    << "lat_deg = " << toml_float(i.lat_deg) << "\nlon_deg = " << toml_float(i.lon_deg)
    << "\nheight_m = " << toml_float(i.height_m)
    << "\ngravity_mps2 = " << toml_float(i.gravity_mps2) << "\n\n"
    << "[imu]\nrate_hz = " << toml_float(i.rate_hz) << "\n\n"
    << "[table]\nouter_axis = " << toml_vec3(i.table.outer_axis_t.normalized())
    << "\ninner_axis = " << toml_vec3(i.table.inner_axis_o.normalized())
    << "\nheading_deg = " << toml_float(i.table.heading_rad * 180.0 / kPi)
    << "\nmount_rpy_deg = [0.0, 0.0, 0.0]\n\n"
    << "[sequence]\nname = \"" << i.sequence_name << "\"\n";
  if (!i.sequence_sha256.empty()) t << "sha256 = \"" << i.sequence_sha256 << "\"\n";
  t << "\n[noise]\narw_deg_per_sqrt_h = " << toml_float(arw_deg_per_sqrt_h)
    << "\nvrw_ug_per_sqrt_hz = " << toml_float(vrw_ug_per_sqrt_hz)
    << "\ndtheta_lsb_rad = " << toml_float(n.dtheta_lsb_rad)
    << "\ndv_lsb_mps = " << toml_float(n.dv_lsb_mps) << "\n";
  return t.str();
}

nlohmann::json json_vec(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }
nlohmann::json json_mat(const Eigen::Matrix3d& m) {
  return {json_vec(m.row(0)), json_vec(m.row(1)), json_vec(m.row(2))};
}

/// truth.json: the injected parameters, every active effect with all its parameters, the noise.
std::string truth_json(const AltRunInfo& i) {
  const AltErrorModel& e = i.unit.errors;
  const AltNoise& n = i.unit.noise;
  nlohmann::json j;
  j["params"] = {{"accel_bias_mps2", json_vec(e.b_a_mps2)},
                 {"accel_M", json_mat(e.M_a)},
                 {"gyro_bias_radps", json_vec(e.b_g_radps)},
                 {"gyro_M", json_mat(e.M_g)},
                 {"table_misalignment_rad", json_vec(i.table.misalignment_rad)}};
  j["effects"] = nlohmann::json::object();
  for (const AltEffectParams& p : alt_effect_table()) {
    if (!alt_effect_active(i.unit.effects, p.name)) continue;
    const std::vector<double> v = alt_effect_values(i.unit.effects, p.name);
    for (size_t k = 0; k < v.size(); ++k) j["effects"][p.name][p.params[k]] = v[k];
  }
  j["noise"] = {{"arw_rad_per_sqrt_s", n.arw_rad_per_sqrt_s},
                {"vrw_mps_per_sqrt_s", n.vrw_mps_per_sqrt_s},
                {"gyro_bias_instability_radps", n.gyro_gm_sigma_radps},
                {"gyro_bias_tau_s", n.gyro_gm_tau_s},
                {"accel_bias_instability_mps2", n.accel_gm_sigma_mps2},
                {"accel_bias_tau_s", n.accel_gm_tau_s},
                {"dtheta_lsb_rad", n.dtheta_lsb_rad},
                {"dv_lsb_mps", n.dv_lsb_mps}};
  return j.dump(2) + "\n";
}

void write_text(const fs::path& path, const std::string& text) {
  std::ofstream f(path, std::ios::binary);
  f << text;
  f.close();
  if (!f) throw std::runtime_error(path.string() + ": cannot write");
}

void write_csvs(const fs::path& dir, const std::vector<AltSample>& samples) {
  std::string imu = "t_s,dtheta_x_rad,dtheta_y_rad,dtheta_z_rad,dv_x_mps,dv_y_mps,dv_z_mps\n";
  std::string tab = "t_s,outer_deg,inner_deg,at_rest\n";
  imu.reserve(samples.size() * 150);
  tab.reserve(samples.size() * 60);
  for (const AltSample& s : samples) {
    append_number(imu, s.t_s);
    for (const Eigen::Vector3d* v : {&s.dtheta_rad, &s.dv_mps})
      for (int i = 0; i < 3; ++i) {
        imu += ',';
        append_number(imu, (*v)(i));
      }
    imu += '\n';
    append_number(tab, s.t_s);
    tab += ',';
    append_number(tab, s.outer_deg);
    tab += ',';
    append_number(tab, s.inner_deg);
    tab += s.at_rest ? ",1\n" : ",0\n";
  }
  write_text(dir / "imu.csv", imu);
  write_text(dir / "table.csv", tab);
}

}  // namespace

void write_alt_archive(const std::string& dir_text, const AltRunInfo& info,
                       const std::vector<AltSample>& samples) {
  if (samples.empty()) throw std::runtime_error(dir_text + ": no samples to write");
  if (!info.table.C_bp.isIdentity(0.0))
    throw std::runtime_error("altsim writes only the identity fixture (mount_rpy_deg = 0)");
  fs::path dir(dir_text);
  if (dir.has_filename() == false) dir = dir.parent_path();  // "out/" -> "out"
  std::error_code ec;
  if (fs::exists(dir, ec) && !(fs::is_directory(dir, ec) && fs::is_empty(dir, ec)))
    throw std::runtime_error(dir.string() + ": exists and is not an empty directory");
  const fs::path parent = dir.has_parent_path() ? dir.parent_path() : fs::path(".");
  std::string tmp = (parent / (dir.filename().string() + ".tmp-XXXXXX")).string();
  if (!::mkdtemp(tmp.data())) throw std::runtime_error(tmp + ": cannot create");
  try {
    write_text(fs::path(tmp) / "run.toml", run_toml(info));
    write_text(fs::path(tmp) / "truth.json", truth_json(info));
    write_csvs(tmp, samples);
    if (fs::exists(dir, ec)) fs::remove(dir);  // the empty target: replaced by the rename
    fs::rename(tmp, dir);
  } catch (...) {
    fs::remove_all(tmp, ec);
    throw;
  }
}

}  // namespace imucal::tools::altsim
