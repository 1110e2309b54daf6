#include "db/archive/run_archive.hpp"

#include <fcntl.h>
#include <stdio.h>  // renameat2 (glibc >= 2.28, _GNU_SOURCE)
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <mutex>

#include "calib/core/conventions.hpp"
#include "calib/core/rotation.hpp"
#include "db/archive/archive_error.hpp"
#include "db/archive/csv.hpp"
#include "db/archive/human_units.hpp"
#include "db/archive/io_util.hpp"
#include "db/archive/toml_util.hpp"
#include "sequences/toml_support.hpp"

namespace imucal::db::archive {

namespace fs = std::filesystem;

namespace {

const std::vector<std::string> kImuColumns = {
    "t_s", "dtheta_x_rad", "dtheta_y_rad", "dtheta_z_rad", "dv_x_mps", "dv_y_mps", "dv_z_mps"};
const std::vector<std::string> kImuOptional = {"temp_c"};
const std::vector<std::string> kTableColumns = {"t_s", "outer_deg", "inner_deg", "at_rest"};
const std::vector<std::string> kGnssColumns = {"t_s", "lat_deg", "lon_deg", "sigma_m"};
const std::vector<std::string> kAttitudeColumns = {"t_s", "roll_deg", "pitch_deg", "yaw_deg",
                                                   "at_rest"};

// Degrees -> rad with one fixed expression; the writer inverts it exactly (human_for_si).
double deg_to_rad(double d) { return d * kDegToRad; }
double rad_to_deg_exact(double r) { return human_for_si(r, r * kRadToDeg, deg_to_rad); }

/// run.toml [prior]'s envelope overrides: key, human unit, SI conversion, the override it sets
/// and its admissible maximum (calib::core::envelope_range()).
struct EnvelopeKey {
  const char* key;
  const char* unit;
  double (*to_si)(double);
  std::optional<double> calib::core::EnvelopeOverrides::*member;
  double max_si;
  const char* range;  ///< as the error states it
};
double deg_per_s_to_si(double h) { return h * kDegToRad; }
double mg_to_si(double h) { return h * 1e3 * kMicroG_mps2; }
double ppm_to_si(double h) { return h * 1e-6; }
double mrad_to_si(double h) { return h * 1e-3; }
const std::vector<EnvelopeKey>& envelope_keys() {
  static const calib::core::EnvelopeRange r = calib::core::envelope_range();
  static const std::vector<EnvelopeKey> keys = {
      {"gyro_bias_deg_per_s", "deg/s", deg_per_s_to_si,
       &calib::core::EnvelopeOverrides::gyro_bias_radps, r.max_gyro_bias_radps, "(0, 100] deg/s"},
      {"accel_bias_mg", "mg", mg_to_si, &calib::core::EnvelopeOverrides::accel_bias_mps2,
       r.max_accel_bias_mps2, "(0, 2000] mg"},
      {"scale_ppm", "ppm", ppm_to_si, &calib::core::EnvelopeOverrides::scale, r.max_scale,
       "(0, 500000] ppm"},
      {"misalignment_mrad", "mrad", mrad_to_si, &calib::core::EnvelopeOverrides::misalignment_rad,
       r.max_misalignment_rad, "(0, 200] mrad"}};
  return keys;
}

std::string join_path(const std::string& dir, const char* name) {
  if (dir.empty()) return name;
  return dir.back() == '/' ? dir + name : dir + "/" + name;
}

std::string strip_trailing_slashes(std::string s) {
  while (s.size() > 1 && s.back() == '/') s.pop_back();
  return s;
}

// ISO 8601 date-time as written by loggers: YYYY-MM-DD[T ]hh:mm[:ss[.fff]][Z|±hh:mm].
bool is_iso8601(const std::string& s) {
  auto digits = [&](size_t pos, size_t n) {
    if (pos + n > s.size()) return false;
    for (size_t i = pos; i < pos + n; ++i)
      if (!std::isdigit(static_cast<unsigned char>(s[i]))) return false;
    return true;
  };
  if (!(digits(0, 4) && s.size() > 4 && s[4] == '-' && digits(5, 2) && s.size() > 7 &&
        s[7] == '-' && digits(8, 2)))
    return false;
  if (s.size() == 10) return true;  // date only
  if (!(s[10] == 'T' || s[10] == 't' || s[10] == ' ')) return false;
  if (!(digits(11, 2) && s.size() > 13 && s[13] == ':' && digits(14, 2))) return false;
  size_t p = 16;
  if (p < s.size() && s[p] == ':') {
    if (!digits(p + 1, 2)) return false;
    p += 3;
    if (p < s.size() && s[p] == '.') {
      ++p;
      const size_t f0 = p;
      while (p < s.size() && std::isdigit(static_cast<unsigned char>(s[p]))) ++p;
      if (p == f0) return false;
    }
  }
  if (p == s.size()) return true;
  if ((s[p] == 'Z' || s[p] == 'z') && p + 1 == s.size()) return true;
  if ((s[p] == '+' || s[p] == '-') && digits(p + 1, 2) && p + 3 < s.size() && s[p + 3] == ':' &&
      digits(p + 4, 2) && p + 6 == s.size())
    return true;
  return false;
}

bool is_hex64(const std::string& s) {
  return s.size() == 64 && std::all_of(s.begin(), s.end(), [](char c) {
           return std::isxdigit(static_cast<unsigned char>(c)) != 0;
         });
}

// [capture]: `complete` (bool) and every CaptureInfo counter (non-negative integer), all required
// (the writer always writes them all); unknown keys are errors, as in the other sections.
CaptureInfo parse_capture_section(const toml::table& t, const std::string& origin) {
  const auto& counters = CaptureInfo::counters();
  auto allowed_list = [&] {
    std::string s = "complete";
    for (const auto& c : counters) s += std::string(", ") + c.first;
    return s;
  };
  auto line_of = [](const toml::node& n) {
    return static_cast<std::size_t>(n.source().begin.line);
  };
  for (auto&& [k, v] : t) {
    bool known = k.str() == "complete";
    for (const auto& c : counters) known = known || k.str() == c.first;
    if (!known)
      throw ArchiveError(origin, k.source().begin.line > 0 ? k.source().begin.line : line_of(v),
                         "unknown key in [capture] (allowed: " + allowed_list() + ")",
                         "capture." + std::string(k.str()));
  }
  CaptureInfo ci;
  const toml::node* complete = t.get("complete");
  if (!complete)
    throw ArchiveError::field_error(origin, "capture.complete", "missing (required in [capture])");
  if (!complete->is_boolean())
    throw ArchiveError(origin, line_of(*complete),
                       std::string("expected a boolean (true/false), got ") +
                           sequences::toml_type_name(complete->type()),
                       "capture.complete");
  ci.complete = complete->as_boolean()->get();
  for (const auto& [name, member] : counters) {
    const toml::node* n = t.get(name);
    const std::string field = std::string("capture.") + name;
    if (!n) throw ArchiveError::field_error(origin, field, "missing (required in [capture])");
    if (!n->is_integer())
      throw ArchiveError(origin, line_of(*n),
                         std::string("expected a non-negative integer, got ") +
                             sequences::toml_type_name(n->type()),
                         field);
    const int64_t v = n->as_integer()->get();
    if (v < 0)
      throw ArchiveError(origin, line_of(*n),
                         "must be a non-negative count, got " + std::to_string(v), field);
    ci.*member = static_cast<uint64_t>(v);
  }
  return ci;
}

struct ParsedRunInfo {
  RunInfo info;
  bool reference_given = false;
  std::size_t reference_line = 0;
  bool dv_raw_integral = false;  ///< [imu] dv_convention = "raw_integral": convert on reading
};

/// The run's identity: serial, software, times, setting and reference kind.
void read_identity(const TomlSection& root, const std::string& origin, ParsedRunInfo& out) {
  RunInfo& ri = out.info;
  const auto serial = root.string("serial");
  if (!serial) throw ArchiveError::field_error(origin, "serial", "missing (required)");
  if (serial->empty()) root.fail("serial", "must not be empty");
  for (char c : *serial)
    if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f)
      root.fail("serial", "contains a control character");
  if (std::isspace(static_cast<unsigned char>(serial->front())) ||
      std::isspace(static_cast<unsigned char>(serial->back())))
    root.fail("serial", "has leading or trailing whitespace");
  ri.serial = *serial;
  ri.software_version = root.string("software_version").value_or("");
  for (const char* k : {"start_time", "end_time"}) {
    const std::string v = root.string_or_datetime(k).value_or("");
    if (!v.empty() && !is_iso8601(v))
      root.fail(k, "'" + v + "' is not an ISO 8601 date-time (e.g. 2024-05-01T10:00:00Z)");
    (std::string(k) == "start_time" ? ri.start_time : ri.end_time) = v;
  }
  if (const auto setting = root.string("setting")) {
    const auto s = calib::core::parse_setting(*setting);
    if (!s)
      root.fail("setting", "must be \"factory\", \"land\" or \"sea\", got \"" + *setting + "\"");
    ri.setting = *s;
  }
  if (const auto ref = root.string("reference")) {
    if (*ref == "table") {
      ri.reference = ReferenceKind::kTable;
    } else if (*ref == "attitude") {
      ri.reference = ReferenceKind::kAttitude;
    } else if (*ref == "none") {
      ri.reference = ReferenceKind::kNone;
    } else {
      root.fail("reference", "must be \"table\", \"attitude\" or \"none\", got \"" + *ref + "\"");
    }
    out.reference_given = true;
    out.reference_line = root.line_of("reference");
  }
}

/// [station]: required, the site within physical bounds.
void read_station(const TomlSection& root, const std::string& origin, RunInfo& ri) {
  const auto station =
      root.section("station", {"name", "lat_deg", "lon_deg", "height_m", "gravity_mps2"});
  if (!station)
    throw ArchiveError::field_error(origin, "station.lat_deg",
                                    "missing (required; no [station] section)");
  ri.station_name = station->string("name").value_or("");
  const double lat_deg = station->required_number("lat_deg");
  const double lon_deg = station->required_number("lon_deg");
  const double height_m = station->required_number("height_m");
  if (std::fabs(lat_deg) > 90.0)
    station->fail("lat_deg", "must be within [-90, 90] deg, got " + format_double(lat_deg));
  if (lon_deg < -180.0 || lon_deg > 360.0)
    station->fail("lon_deg", "must be within [-180, 360] deg, got " + format_double(lon_deg));
  if (height_m < -12000.0 || height_m > 100000.0)
    station->fail("height_m", "must be within [-12000, 100000] m above the ellipsoid, got " +
                                  format_double(height_m));
  ri.site.lat_rad = deg_to_rad(lat_deg);
  ri.site.lon_rad = deg_to_rad(lon_deg);
  ri.site.height_m = height_m;
  if (const auto g = station->number("gravity_mps2")) {
    if (*g < 9.7 || *g > 9.9)
      station->fail(
          "gravity_mps2",
          "must be a surveyed gravity magnitude within [9.7, 9.9] m/s^2, got " + format_double(*g));
    ri.site.gravity_mps2 = *g;
  }
}

/// [imu]: required rate, and the dv convention of the data.
void read_imu(const TomlSection& root, const std::string& origin, ParsedRunInfo& out) {
  RunInfo& ri = out.info;
  const auto imu = root.section("imu", {"rate_hz", "dv_convention", "protocol"});
  if (!imu)
    throw ArchiveError::field_error(origin, "imu.rate_hz", "missing (required; no [imu] section)");
  ri.imu_rate_hz = imu->required_number("rate_hz");
  if (!(ri.imu_rate_hz > 0.0 && ri.imu_rate_hz <= 100000.0))
    imu->fail("rate_hz", "must be within (0, 100000] Hz, got " + format_double(ri.imu_rate_hz));
  if (const auto p = imu->string("protocol")) ri.imu_protocol = *p;
  if (const auto conv = imu->string("dv_convention")) {
    if (*conv == "raw_integral") {
      out.dv_raw_integral = true;
    } else if (*conv != "interval_start") {
      imu->fail("dv_convention",
                "must be \"interval_start\" (dv in the body frame at the start of the "
                "interval, the archive's convention) or \"raw_integral\" (plain ∫f dt), got \"" +
                    *conv + "\"");
    }
  }
}

/// [table], [sequence], [noise]: optional, each checked where given.
void read_optional_sections(const TomlSection& root, RunInfo& ri) {
  if (const auto t = root.section("table", {"outer_axis", "inner_axis", "heading_deg",
                                            "mount_rpy_deg", "slot", "lever_arm_m"})) {
    for (const char* k : {"outer_axis", "inner_axis"})
      if (const auto a = t->vec3(k)) {
        if (std::fabs(a->norm() - 1.0) > 1e-3)
          t->fail(k, "must be a unit vector (norm " + format_double(a->norm()) + ")");
        (std::string(k) == "outer_axis" ? ri.table.outer_axis_t : ri.table.inner_axis_o) = *a;
      }
    if (const auto h = t->number("heading_deg")) ri.table.heading_rad = deg_to_rad(*h);
    if (const auto m = t->vec3("mount_rpy_deg")) {
      if (std::fabs((*m)(1)) > 90.0)
        t->fail("mount_rpy_deg", "pitch (second element) must be within [-90, 90] deg");
      ri.table.mount_rpy_rad = {deg_to_rad((*m)(0)), deg_to_rad((*m)(1)), deg_to_rad((*m)(2))};
    }
    ri.table.slot = t->string("slot").value_or("");
    if (const auto r = t->vec3("lever_arm_m")) {
      if (!(r->array().abs() <= 2.0).all())
        t->fail("lever_arm_m", "must be within 2 m of the rotation centre on every axis");
      ri.table.lever_arm_m = *r;
    }
  }
  if (const auto s = root.section("sequence", {"name", "sha256"})) {
    ri.sequence_name = s->string("name").value_or("");
    ri.sequence_sha256 = s->string("sha256").value_or("");
    if (!ri.sequence_sha256.empty() && !is_hex64(ri.sequence_sha256))
      s->fail("sha256", "must be 64 hexadecimal digits");
  }
  if (const auto p =
          root.section("prior", {"grade", "min_rest_s", "first_rest_s", "gyro_bias_deg_per_s",
                                 "accel_bias_mg", "scale_ppm", "misalignment_mrad"})) {
    for (const EnvelopeKey& k : envelope_keys())
      if (const auto v = p->number(k.key)) {
        const double si = k.to_si(*v);
        if (!(si > 0.0 && si <= k.max_si * (1.0 + 1e-12)))
          p->fail(k.key, std::string("must be in ") + k.range + ", got " + format_double(*v) + " " +
                             k.unit);
        ri.prior_overrides.*k.member = si;
      }
    if (const auto g = p->string("grade")) {
      const auto grade = calib::core::parse_grade(*g);
      if (!grade)
        p->fail("grade", "must be \"navigation\", \"tactical\" or \"mems\", got \"" + *g + "\"");
      ri.grade = *grade;
    }
    if (const auto m = p->number("min_rest_s")) {
      if (!(*m >= 0.5 && *m <= 600.0)) p->fail("min_rest_s", "must be in [0.5, 600] s");
      ri.min_rest_s = *m;
    }
    if (const auto m = p->number("first_rest_s")) {
      if (!(*m >= 0.5 && *m <= 600.0)) p->fail("first_rest_s", "must be in [0.5, 600] s");
      ri.first_rest_s = *m;
    }
  }
  if (const auto n = root.section("noise", {"arw_deg_per_sqrt_h", "vrw_ug_per_sqrt_hz",
                                            "dtheta_lsb_rad", "dv_lsb_mps", "lsb_rounding"})) {
    for (const auto& [key, member] : {std::pair{"dtheta_lsb_rad", &RunInfo::dtheta_lsb_rad},
                                      std::pair{"dv_lsb_mps", &RunInfo::dv_lsb_mps}})
      if (const auto q = n->number(key)) {
        if (!(*q >= 0.0 && *q < 1.0)) n->fail(key, "must be in [0, 1) (0 = no quantisation)");
        ri.*member = *q;
      }
    if (const auto r = n->string("lsb_rounding")) {
      const auto rounding = calib::core::parse_lsb_rounding(*r);
      if (!rounding)
        n->fail("lsb_rounding",
                "must be \"carried\" (an output register's) or \"per_sample\" "
                "(a logger of counts), got \"" +
                    *r + "\"");
      ri.lsb_rounding = *rounding;
    }
    if (const auto a = n->number("arw_deg_per_sqrt_h")) {
      if (!(*a > 0.0)) n->fail("arw_deg_per_sqrt_h", "must be > 0 (it weights the gyro data)");
      ri.arw_rad_per_sqrt_s = arw_to_si(*a);
    }
    if (const auto v = n->number("vrw_ug_per_sqrt_hz")) {
      if (!(*v > 0.0))
        n->fail("vrw_ug_per_sqrt_hz", "must be > 0 (it weights the accelerometer data)");
      ri.vrw_mps_per_sqrt_s = vrw_to_si(*v);
    }
  }
}

ParsedRunInfo parse_run_info_impl(const std::string& text, const std::string& origin) {
  const toml::table tbl = parse_toml_text(text, origin);
  const TomlSection root(
      tbl, origin, "",
      {"serial", "software_version", "start_time", "end_time", "reference", "setting", "station",
       "imu", "table", "sequence", "prior", "noise", "capture"});
  ParsedRunInfo out;
  read_identity(root, origin, out);
  read_station(root, origin, out.info);
  read_imu(root, origin, out);
  read_optional_sections(root, out.info);
  if (const toml::node* cn = tbl.get("capture")) {
    if (!cn->is_table())
      root.fail("capture", std::string("expected a table [capture], got ") +
                               sequences::toml_type_name(cn->type()));
    out.info.capture = parse_capture_section(*cn->as_table(), origin);
  }
  return out;
}

const char* reference_name(ReferenceKind k) {
  switch (k) {
    case ReferenceKind::kTable:
      return "table";
    case ReferenceKind::kAttitude:
      return "attitude";
    case ReferenceKind::kNone:
      return "none";
  }
  return "none";
}

// at_rest cell: exactly 0 or 1.
bool rest_flag(const CsvTable& t, size_t row, size_t col) {
  const double v = t.at(row, col);
  if (v == 1.0) return true;
  if (v == 0.0) return false;
  throw ArchiveError::column_error(t.file, CsvTable::line_of_row(row), t.columns[col],
                                   "must be 0 or 1, got " + format_double(v));
}

void check_has_rows(const CsvTable& t) {
  if (t.num_rows == 0) throw ArchiveError(t.file, 2, "no data rows after the header");
}

}  // namespace

calib::core::TableGeometry TableSetup::geometry() const {
  calib::core::TableGeometry g;
  g.outer_axis_t = outer_axis_t.normalized();
  g.inner_axis_o = inner_axis_o.normalized();
  g.heading_rad = heading_rad;
  g.C_bp = calib::core::euler_to_C_bn(mount_rpy_rad(0), mount_rpy_rad(1), mount_rpy_rad(2));
  return g;
}

TableSetup TableSetup::from_geometry(const calib::core::TableGeometry& g) {
  TableSetup s;
  s.outer_axis_t = g.outer_axis_t;
  s.inner_axis_o = g.inner_axis_o;
  s.heading_rad = g.heading_rad;
  if (!((g.C_bp.transpose() * g.C_bp - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() < 1e-9 &&
        g.C_bp.determinant() > 0.0))
    throw ArchiveError::field_error("<table geometry>", "C_bp", "is not a rotation matrix");
  s.mount_rpy_rad = calib::core::C_bn_to_euler(g.C_bp);
  return s;
}

RunInfo parse_run_info(const std::string& text, const std::string& origin) {
  return parse_run_info_impl(text, origin).info;
}

std::string run_info_text(const RunInfo& ri) {
  TomlWriter w;
  w.comment("Run archive metadata (db/archive/FORMAT.md).");
  w.key("serial", ri.serial);
  if (!ri.software_version.empty()) w.key("software_version", ri.software_version);
  if (!ri.start_time.empty()) w.key("start_time", ri.start_time);
  if (!ri.end_time.empty()) w.key("end_time", ri.end_time);
  if (ri.setting != calib::core::Setting::kFactory)
    w.key("setting", calib::core::setting_name(ri.setting));
  w.key("reference", reference_name(ri.reference));
  w.section("station");
  if (!ri.station_name.empty()) w.key("name", ri.station_name);
  w.key("lat_deg", rad_to_deg_exact(ri.site.lat_rad));
  w.key("lon_deg", rad_to_deg_exact(ri.site.lon_rad));
  w.key("height_m", ri.site.height_m);
  if (ri.site.gravity_mps2) w.key("gravity_mps2", *ri.site.gravity_mps2);
  w.section("imu");
  w.key("rate_hz", ri.imu_rate_hz);
  if (!ri.imu_protocol.empty()) w.key("protocol", ri.imu_protocol);
  w.section("table");
  w.key("outer_axis", ri.table.outer_axis_t);
  w.key("inner_axis", ri.table.inner_axis_o);
  w.key("heading_deg", rad_to_deg_exact(ri.table.heading_rad));
  w.key("mount_rpy_deg", Eigen::Vector3d(rad_to_deg_exact(ri.table.mount_rpy_rad(0)),
                                         rad_to_deg_exact(ri.table.mount_rpy_rad(1)),
                                         rad_to_deg_exact(ri.table.mount_rpy_rad(2))));
  if (!ri.table.slot.empty()) w.key("slot", ri.table.slot);
  if (!ri.table.lever_arm_m.isZero()) w.key("lever_arm_m", ri.table.lever_arm_m);
  if (!ri.sequence_name.empty() || !ri.sequence_sha256.empty()) {
    w.section("sequence");
    if (!ri.sequence_name.empty()) w.key("name", ri.sequence_name);
    if (!ri.sequence_sha256.empty()) w.key("sha256", ri.sequence_sha256);
  }
  // Written only when it says something: a navigation-grade archive stays as it always was.
  if (ri.grade != calib::core::Grade::kNavigation || ri.min_rest_s > 0.0 || ri.first_rest_s > 0.0 ||
      ri.prior_overrides.any()) {
    w.section("prior");
    w.key("grade", calib::core::grade_name(ri.grade));
    if (ri.min_rest_s > 0.0) w.key("min_rest_s", ri.min_rest_s);
    if (ri.first_rest_s > 0.0) w.key("first_rest_s", ri.first_rest_s);
    for (const EnvelopeKey& k : envelope_keys())
      if (const auto& v = ri.prior_overrides.*k.member)
        w.key(k.key, human_for_si(*v, *v / k.to_si(1.0), k.to_si));
  }
  w.section("noise");
  w.key("arw_deg_per_sqrt_h",
        human_for_si(ri.arw_rad_per_sqrt_s, ri.arw_rad_per_sqrt_s / arw_to_si(1.0), arw_to_si));
  w.key("vrw_ug_per_sqrt_hz",
        human_for_si(ri.vrw_mps_per_sqrt_s, ri.vrw_mps_per_sqrt_s / vrw_to_si(1.0), vrw_to_si));
  if (ri.dtheta_lsb_rad != calib::core::NoiseModel{}.dtheta_lsb_rad ||
      ri.dv_lsb_mps != calib::core::NoiseModel{}.dv_lsb_mps) {
    w.key("dtheta_lsb_rad", ri.dtheta_lsb_rad);
    w.key("dv_lsb_mps", ri.dv_lsb_mps);
  }
  // Written only when not the default, so an archive of the station's protocol reads as before.
  if (ri.lsb_rounding != calib::core::LsbRounding::kCarried)
    w.key("lsb_rounding", calib::core::lsb_rounding_name(ri.lsb_rounding));
  std::string text = w.text();
  if (ri.capture) {
    // TomlWriter has no integer/boolean keys; counters are written as TOML integers (exact).
    text += "\n[capture]\n";
    text += std::string("complete = ") + (ri.capture->complete ? "true" : "false") + "\n";
    for (const auto& [name, member] : CaptureInfo::counters()) {
      const uint64_t v = (*ri.capture).*member;
      if (v > static_cast<uint64_t>(INT64_MAX))
        throw ArchiveError::field_error(
            "run.toml", std::string("capture.") + name,
            "count " + std::to_string(v) + " exceeds the TOML integer range");
      text += std::string(name) + " = " + std::to_string(v) + "\n";
    }
  }
  return text;
}

const std::vector<std::pair<const char*, uint64_t CaptureInfo::*>>& CaptureInfo::counters() {
  static const std::vector<std::pair<const char*, uint64_t CaptureInfo::*>> list = {
      {"frames_received", &CaptureInfo::frames_received},
      {"frames_logged", &CaptureInfo::frames_logged},
      {"frames_foreign", &CaptureInfo::frames_foreign},
      {"frames_error", &CaptureInfo::frames_error},
      {"frames_malformed", &CaptureInfo::frames_malformed},
      {"frames_duplicate", &CaptureInfo::frames_duplicate},
      {"frames_out_of_order", &CaptureInfo::frames_out_of_order},
      {"frames_discarded", &CaptureInfo::frames_discarded},
      {"rx_overflow", &CaptureInfo::rx_overflow},
      {"samples_decoded", &CaptureInfo::samples_decoded},
      {"samples_lost", &CaptureInfo::samples_lost},
      {"samples_corrupt", &CaptureInfo::samples_corrupt},
      {"samples_incomplete", &CaptureInfo::samples_incomplete},
      {"samples_late", &CaptureInfo::samples_late},
      {"samples_filled", &CaptureInfo::samples_filled},
      {"max_gap_samples", &CaptureInfo::max_gap_samples},
      {"imu_resets", &CaptureInfo::imu_resets},
      {"rows_written", &CaptureInfo::rows_written},
      {"rest_samples", &CaptureInfo::rest_samples},
  };
  return list;
}

bool operator==(const CaptureInfo& a, const CaptureInfo& b) {
  if (a.complete != b.complete) return false;
  for (const auto& c : CaptureInfo::counters())
    if (a.*(c.second) != b.*(c.second)) return false;
  return true;
}

namespace {

/// imu.csv rows straight into RunArchive::imu. dt_s is set after the parse: it needs the row
/// before, which may be the other thread's.
class ImuRowSink final : public CsvRowSink {
 public:
  ImuRowSink(calib::core::ImuSeries& imu, bool dv_raw_integral)
      : imu_(imu), dv_raw_integral_(dv_raw_integral) {}
  void begin(const std::vector<std::string>& columns, size_t num_rows) override {
    has_temp_ = columns.size() == 8;
    imu_.resize(num_rows);
  }
  void row(size_t k, const double* v) override {
    calib::core::ImuIncrement& s = imu_[k];
    s.t_s = v[0];
    s.dtheta_rad = {v[1], v[2], v[3]};
    s.dv_mps = {v[4], v[5], v[6]};
    s.temp_c = has_temp_ ? v[7] : nan_;
    // Raw integral ∫ f_b dt -> the body frame at the interval start (ARCHITECTURE §3,
    // conventions.hpp): first-order rotation compensation; sculling inside one sample is not
    // recoverable here.
    if (dv_raw_integral_) {
      const Eigen::Vector3d v_raw = s.dv_mps;
      s.dv_mps = v_raw + 0.5 * s.dtheta_rad.cross(v_raw);
    }
  }

 private:
  calib::core::ImuSeries& imu_;
  bool dv_raw_integral_;
  bool has_temp_ = false;
  const double nan_ = std::nan("");  // temp_c when imu.csv has no temp_c column
};

void read_imu(const std::string& path, bool dv_raw_integral, RunArchive& a) {
  ImuRowSink sink(a.imu, dv_raw_integral);
  read_csv_rows(path, CsvSpec{kImuColumns, kImuOptional, true}, sink);
  if (a.imu.empty()) throw ArchiveError(path, 2, "no data rows after the header");
  // First interval: the nominal one; afterwards the time difference (strictly positive).
  a.imu[0].dt_s = 1.0 / a.info.imu_rate_hz;
  for (size_t k = 1; k < a.imu.size(); ++k) a.imu[k].dt_s = a.imu[k].t_s - a.imu[k - 1].t_s;
}

/// table.csv rows straight into RunArchive::table. An at_rest other than 0 or 1 is remembered
/// (the first in file order) and reported after the parse, as the check after a CsvTable was.
class TableRowSink final : public CsvRowSink {
 public:
  explicit TableRowSink(std::vector<calib::core::TableSample>& table) : table_(table) {}
  void begin(const std::vector<std::string>&, size_t num_rows) override { table_.resize(num_rows); }
  void row(size_t k, const double* v) override {
    table_[k] = {v[0], deg_to_rad(v[1]), deg_to_rad(v[2]), v[3] == 1.0};
    if (v[3] != 0.0 && v[3] != 1.0) {
      const std::lock_guard<std::mutex> lock(bad_mutex_);  // both threads may find one
      if (k < bad_row_) {
        bad_row_ = k;
        bad_value_ = v[3];
      }
    }
  }
  /// The first row whose at_rest is neither 0 nor 1, if any.
  std::optional<std::pair<size_t, double>> bad_rest_flag() const {
    if (bad_row_ == kNone) return std::nullopt;
    return std::make_pair(bad_row_, bad_value_);
  }

 private:
  static constexpr size_t kNone = static_cast<size_t>(-1);
  std::vector<calib::core::TableSample>& table_;
  std::mutex bad_mutex_;
  size_t bad_row_ = kNone;
  double bad_value_ = 0.0;
};

void read_table(const std::string& path, RunArchive& a) {
  TableRowSink sink(a.table);
  read_csv_rows(path, CsvSpec{kTableColumns, {}, true}, sink);
  if (a.table.empty()) throw ArchiveError(path, 2, "no data rows after the header");
  if (const auto bad = sink.bad_rest_flag())
    throw ArchiveError::column_error(path, CsvTable::line_of_row(bad->first), "at_rest",
                                     "must be 0 or 1, got " + format_double(bad->second));
}

/// gnss.csv: required at sea, optional elsewhere; every fix inside the IMU's time span.
void read_gnss(const std::string& dir, RunArchive& a) {
  std::error_code ec;
  const std::string gnss_csv = join_path(dir, "gnss.csv");
  if (!fs::exists(gnss_csv, ec)) {
    if (a.info.setting == calib::core::Setting::kSea)
      throw ArchiveError(gnss_csv,
                         "missing: a sea run needs GNSS position fixes (there is no zero "
                         "velocity at sea; paper §IV-D)");
    return;
  }
  const CsvTable t = read_csv(gnss_csv, CsvSpec{kGnssColumns, {}, true});
  check_has_rows(t);
  const double t_first = a.imu.front().t_s - a.imu.front().dt_s, t_last = a.imu.back().t_s;
  a.gnss.resize(t.num_rows);
  for (size_t k = 0; k < t.num_rows; ++k) {
    const size_t line = CsvTable::line_of_row(k);
    const double ts = t.at(k, 0), lat = t.at(k, 1), lon = t.at(k, 2), sig = t.at(k, 3);
    if (k > 0 && !(ts > t.at(k - 1, 0)))
      throw ArchiveError::column_error(gnss_csv, line, "t_s",
                                       "must increase (previous row " +
                                           format_double(t.at(k - 1, 0)) + ", this row " +
                                           format_double(ts) + ")");
    if (ts < t_first || ts > t_last)
      throw ArchiveError::column_error(gnss_csv, line, "t_s",
                                       format_double(ts) + " is outside the IMU's time span [" +
                                           format_double(t_first) + ", " + format_double(t_last) +
                                           "] s (both files share one clock)");
    if (std::fabs(lat) > 90.0)
      throw ArchiveError::column_error(gnss_csv, line, "lat_deg",
                                       "must be within [-90, 90], got " + format_double(lat));
    if (lon < -180.0 || lon > 360.0)
      throw ArchiveError::column_error(gnss_csv, line, "lon_deg",
                                       "must be within [-180, 360], got " + format_double(lon));
    if (!(sig > 0.0 && sig < 1000.0))
      throw ArchiveError::column_error(gnss_csv, line, "sigma_m",
                                       "must be within (0, 1000) m, got " + format_double(sig));
    a.gnss[k] = {ts, deg_to_rad(lat), deg_to_rad(lon), sig};
  }
}

}  // namespace

RunArchive read_archive(const std::string& dir_in) {
  const std::string dir = strip_trailing_slashes(dir_in);
  std::error_code ec;
  if (!fs::is_directory(dir, ec))
    throw ArchiveError(dir, fs::exists(dir, ec)
                                ? "is not a directory (a run archive is a directory)"
                                : "no such run archive directory");
  RunArchive a;
  a.origin = dir;
  const std::string run_toml = join_path(dir, "run.toml");
  if (!fs::exists(run_toml, ec))
    throw ArchiveError(run_toml, "missing: every run archive needs run.toml");
  const ParsedRunInfo parsed = parse_run_info_impl(read_text_file(run_toml), run_toml);
  a.info = parsed.info;

  const std::string table_csv = join_path(dir, "table.csv");
  const std::string attitude_csv = join_path(dir, "attitude.csv");
  const bool has_table = fs::exists(table_csv, ec);
  const bool has_attitude = fs::exists(attitude_csv, ec);
  if (has_table && has_attitude)
    throw ArchiveError(dir,
                       "both table.csv and attitude.csv are present; an archive carries exactly "
                       "one reference (remove one)");
  const bool field = a.info.setting != calib::core::Setting::kFactory;
  if (!has_table && !has_attitude && !field)
    throw ArchiveError(dir,
                       "neither table.csv nor attitude.csv is present; a factory run needs "
                       "exactly one reference (a land or sea run says so in run.toml: setting)");
  const ReferenceKind present = has_table      ? ReferenceKind::kTable
                                : has_attitude ? ReferenceKind::kAttitude
                                               : ReferenceKind::kNone;
  if (parsed.reference_given && parsed.info.reference != present)
    throw ArchiveError(run_toml, parsed.reference_line,
                       std::string("says \"") + reference_name(parsed.info.reference) +
                           "\" but the archive contains " +
                           (has_table      ? "table.csv"
                            : has_attitude ? "attitude.csv"
                                           : "no reference file"),
                       "reference");
  a.info.reference = present;

  read_imu(join_path(dir, "imu.csv"), parsed.dv_raw_integral, a);
  if (has_table) {
    read_table(table_csv, a);
  } else if (has_attitude) {
    const CsvTable t = read_csv(attitude_csv, CsvSpec{kAttitudeColumns, {}, true});
    check_has_rows(t);
    a.attitude.resize(t.num_rows);
    for (size_t k = 0; k < t.num_rows; ++k) {
      if (std::fabs(t.at(k, 2)) > 90.0)
        throw ArchiveError::column_error(
            t.file, CsvTable::line_of_row(k), "pitch_deg",
            "must be within [-90, 90] deg, got " + format_double(t.at(k, 2)));
      a.attitude[k] = {t.at(k, 0), deg_to_rad(t.at(k, 1)), deg_to_rad(t.at(k, 2)),
                       deg_to_rad(t.at(k, 3)), rest_flag(t, k, 4)};
    }
  }

  read_gnss(dir, a);

  const std::string truth_json = join_path(dir, "truth.json");
  if (fs::exists(truth_json, ec)) a.truth = read_truth_json(truth_json);
  return a;
}

namespace {

void write_contents(const std::string& tmp, const RunArchive& a, const std::string& final_dir) {
  // run.toml, self-checked: the reader must accept exactly what we write.
  const std::string toml_text = run_info_text(a.info);
  parse_run_info(toml_text, join_path(final_dir, "run.toml") + " (as being written)");
  write_file_durable(join_path(tmp, "run.toml"), toml_text);

  // imu.csv: temp_c only if every sample has a temperature.
  const std::string imu_name = join_path(final_dir, "imu.csv");
  size_t n_temp = 0;
  for (const auto& s : a.imu) n_temp += std::isfinite(s.temp_c) ? 1 : 0;
  if (n_temp != 0 && n_temp != a.imu.size())
    throw ArchiveError::column_error(
        imu_name, 0, "temp_c",
        "known for " + std::to_string(n_temp) + " of " + std::to_string(a.imu.size()) +
            " samples; write all temperatures or none (set all to NaN)");
  std::vector<std::string> cols = kImuColumns;
  if (n_temp) cols.push_back("temp_c");
  {
    CsvWriter w(join_path(tmp, "imu.csv"), cols, true);
    double row[8];
    const double dt0 = 1.0 / a.info.imu_rate_hz;
    for (size_t k = 0; k < a.imu.size(); ++k) {
      const calib::core::ImuIncrement& s = a.imu[k];
      // dt is not stored: the reader derives it from t_s. Refuse an archive that would read back a
      // different interval than the one in memory.
      const double dt_file = k == 0 ? dt0 : s.t_s - a.imu[k - 1].t_s;
      if (!(std::fabs(s.dt_s - dt_file) <= 1e-6 * dt0))
        throw ArchiveError(imu_name, CsvTable::line_of_row(k),
                           "sample dt_s = " + format_double(s.dt_s) +
                               " s but the archive derives " + format_double(dt_file) +
                               " s from t_s (first sample: 1/rate_hz)");
      row[0] = s.t_s;
      for (int i = 0; i < 3; ++i) {
        row[1 + i] = s.dtheta_rad(i);
        row[4 + i] = s.dv_mps(i);
      }
      row[7] = s.temp_c;
      w.write_row(row, cols.size());
    }
    w.close();
  }

  if (!a.gnss.empty()) {
    CsvWriter w(join_path(tmp, "gnss.csv"), kGnssColumns, true);
    for (const auto& g : a.gnss)
      w.write_row({g.t_s, rad_to_deg_exact(g.lat_rad), rad_to_deg_exact(g.lon_rad), g.sigma_m});
    w.close();
  }
  if (a.info.reference == ReferenceKind::kTable) {
    CsvWriter w(join_path(tmp, "table.csv"), kTableColumns, true);
    for (const auto& s : a.table)
      w.write_row({s.t_s, rad_to_deg_exact(s.outer_rad), rad_to_deg_exact(s.inner_rad),
                   s.at_rest ? 1.0 : 0.0});
    w.close();
  } else if (a.info.reference == ReferenceKind::kAttitude) {
    CsvWriter w(join_path(tmp, "attitude.csv"), kAttitudeColumns, true);
    for (const auto& s : a.attitude)
      w.write_row({s.t_s, rad_to_deg_exact(s.roll_rad), rad_to_deg_exact(s.pitch_rad),
                   rad_to_deg_exact(s.yaw_rad), s.at_rest ? 1.0 : 0.0});
    w.close();
  }
  if (a.truth) write_file_durable(join_path(tmp, "truth.json"), truth_json_text(*a.truth));
  fsync_directory(tmp);
}

}  // namespace

void check_archive_target(const std::string& dir, bool overwrite,
                          const std::string& how_to_replace) {
  std::error_code ec;
  if (!fs::exists(dir, ec)) return;
  if (!fs::is_directory(dir, ec)) throw ArchiveError(dir, "exists and is not a directory");
  if (!overwrite && !fs::is_empty(dir, ec))
    throw ArchiveError(dir, "exists and is not empty; refusing to overwrite a run archive (" +
                                how_to_replace + ")");
}

void write_archive(const std::string& dir_in, const RunArchive& a, bool overwrite) {
  const std::string dir = strip_trailing_slashes(dir_in);
  if (dir.empty()) throw ArchiveError("<archive>", "empty directory name");
  // Structural checks first: nothing touches the disk for an archive the reader would reject.
  if (a.imu.empty()) throw ArchiveError(dir, "cannot write an archive without IMU samples");
  const ReferenceKind ref = a.info.reference;
  const bool ref_ok = ref == ReferenceKind::kTable      ? !a.table.empty() && a.attitude.empty()
                      : ref == ReferenceKind::kAttitude ? !a.attitude.empty() && a.table.empty()
                                                        : a.table.empty() && a.attitude.empty();
  if (!ref_ok)
    throw ArchiveError(dir, std::string("info.reference is \"") + reference_name(ref) +
                                "\": exactly that reference must be non-empty and the others "
                                "empty (table: " +
                                std::to_string(a.table.size()) +
                                " rows, attitude: " + std::to_string(a.attitude.size()) + " rows)");
  if (ref == ReferenceKind::kNone && a.info.setting == calib::core::Setting::kFactory)
    throw ArchiveError(dir, "a factory run needs a reference (table or attitude log)");
  if (a.info.setting == calib::core::Setting::kSea && a.gnss.empty())
    throw ArchiveError(dir, "a sea run needs GNSS fixes (gnss.csv)");

  check_archive_target(dir, overwrite);
  std::error_code ec;
  const bool target_exists = fs::exists(dir, ec) && !fs::is_empty(dir, ec);
  const fs::path parent = fs::path(dir).parent_path();
  const std::string parent_dir = parent.empty() ? "." : parent.string();
  fs::create_directories(parent_dir, ec);
  if (ec) throw ArchiveError(parent_dir, "cannot create parent directory: " + ec.message());

  std::string tmp = dir + ".tmp-XXXXXX";
  if (!::mkdtemp(tmp.data()))
    throw ArchiveError(dir,
                       std::string("cannot create temporary directory: ") + std::strerror(errno));
  try {
    write_contents(tmp, a, dir);
    if (!target_exists) {
      // rename(2) onto a missing or empty directory is atomic.
      if (::rename(tmp.c_str(), dir.c_str()) != 0)
        throw ArchiveError(
            dir, std::string("cannot move the archive into place: ") + std::strerror(errno));
    } else {
      // Swap atomically; the old archive then lives at tmp and is removed below.
      if (::renameat2(AT_FDCWD, tmp.c_str(), AT_FDCWD, dir.c_str(), RENAME_EXCHANGE) != 0) {
        if (errno != EINVAL && errno != ENOSYS)
          throw ArchiveError(dir,
                             std::string("cannot replace the archive: ") + std::strerror(errno));
        // File system without RENAME_EXCHANGE: move the old one aside, then the new one in.
        std::string old = dir + ".old-XXXXXX";
        if (!::mkdtemp(old.data()))
          throw ArchiveError(
              dir, std::string("cannot create temporary directory: ") + std::strerror(errno));
        if (::rename(dir.c_str(), old.c_str()) != 0) {
          const int e = errno;
          fs::remove_all(old, ec);
          throw ArchiveError(dir,
                             std::string("cannot move the old archive aside: ") + std::strerror(e));
        }
        if (::rename(tmp.c_str(), dir.c_str()) != 0) {
          const int e = errno;
          ::rename(old.c_str(), dir.c_str());  // put the old one back
          throw ArchiveError(
              dir, std::string("cannot move the archive into place: ") + std::strerror(e));
        }
        fs::remove_all(old, ec);
      } else {
        fs::remove_all(tmp, ec);
      }
    }
  } catch (...) {
    fs::remove_all(tmp, ec);
    throw;
  }
  fsync_directory(parent_dir);
}

double data_span_s(const RunArchive& ar) {
  if (ar.imu.empty()) return 0.0;
  return ar.imu.back().t_s - ar.imu.front().t_s + ar.imu.front().dt_s;
}

}  // namespace imucal::db::archive
