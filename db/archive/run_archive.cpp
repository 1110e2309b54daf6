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

#include "calib/checks/data_check.hpp"
#include "calib/core/conventions.hpp"
#include "calib/core/rotation.hpp"
#include "calib/effects/effect_compensation.hpp"
#include "db/archive/archive_error.hpp"
#include "db/archive/csv.hpp"
#include "db/archive/io_util.hpp"
#include "db/archive/toml_util.hpp"
#include "sequences/toml_support.hpp"

namespace imucal::archive {

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
double arw_to_si(double h) { return h * kDegToRad / 60.0; }  // deg/√h -> rad/√s
double vrw_to_si(double h) { return h * kMicroG_mps2; }      // µg/√Hz -> (m/s)/√s

/// run.toml [prior]'s envelope overrides: key, human unit, SI conversion, the override it sets
/// and its admissible maximum (calib::envelope_range()).
struct EnvelopeKey {
  const char* key;
  const char* unit;
  double (*to_si)(double);
  std::optional<double> calib::EnvelopeOverrides::*member;
  double max_si;
  const char* range;  ///< as the error states it
};
double deg_per_s_to_si(double h) { return h * kDegToRad; }
double mg_to_si(double h) { return h * 1e3 * kMicroG_mps2; }
double ppm_to_si(double h) { return h * 1e-6; }
double mrad_to_si(double h) { return h * 1e-3; }
const std::vector<EnvelopeKey>& envelope_keys() {
  static const calib::EnvelopeRange r = calib::envelope_range();
  static const std::vector<EnvelopeKey> keys = {
      {"gyro_bias_deg_per_s", "deg/s", deg_per_s_to_si, &calib::EnvelopeOverrides::gyro_bias_radps,
       r.max_gyro_bias_radps, "(0, 100] deg/s"},
      {"accel_bias_mg", "mg", mg_to_si, &calib::EnvelopeOverrides::accel_bias_mps2,
       r.max_accel_bias_mps2, "(0, 2000] mg"},
      {"scale_ppm", "ppm", ppm_to_si, &calib::EnvelopeOverrides::scale, r.max_scale,
       "(0, 500000] ppm"},
      {"misalignment_mrad", "mrad", mrad_to_si, &calib::EnvelopeOverrides::misalignment_rad,
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
    const auto s = calib::parse_setting(*setting);
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
  if (const auto p = root.section("prior", {"grade", "min_rest_s", "gyro_bias_deg_per_s",
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
      const auto grade = calib::parse_grade(*g);
      if (!grade)
        p->fail("grade", "must be \"navigation\", \"tactical\" or \"mems\", got \"" + *g + "\"");
      ri.grade = *grade;
    }
    if (const auto m = p->number("min_rest_s")) {
      if (!(*m >= 0.5 && *m <= 600.0)) p->fail("min_rest_s", "must be in [0.5, 600] s");
      ri.min_rest_s = *m;
    }
  }
  if (const auto n = root.section(
          "noise", {"arw_deg_per_sqrt_h", "vrw_ug_per_sqrt_hz", "dtheta_lsb_rad", "dv_lsb_mps"})) {
    for (const auto& [key, member] : {std::pair{"dtheta_lsb_rad", &RunInfo::dtheta_lsb_rad},
                                      std::pair{"dv_lsb_mps", &RunInfo::dv_lsb_mps}})
      if (const auto q = n->number(key)) {
        if (!(*q >= 0.0 && *q < 1.0)) n->fail(key, "must be in [0, 1) (0 = no quantisation)");
        ri.*member = *q;
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

calib::TableGeometry TableSetup::geometry() const {
  calib::TableGeometry g;
  g.outer_axis_t = outer_axis_t.normalized();
  g.inner_axis_o = inner_axis_o.normalized();
  g.heading_rad = heading_rad;
  g.C_bp = calib::euler_to_C_bn(mount_rpy_rad(0), mount_rpy_rad(1), mount_rpy_rad(2));
  return g;
}

TableSetup TableSetup::from_geometry(const calib::TableGeometry& g) {
  TableSetup s;
  s.outer_axis_t = g.outer_axis_t;
  s.inner_axis_o = g.inner_axis_o;
  s.heading_rad = g.heading_rad;
  if (!((g.C_bp.transpose() * g.C_bp - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() < 1e-9 &&
        g.C_bp.determinant() > 0.0))
    throw ArchiveError::field_error("<table geometry>", "C_bp", "is not a rotation matrix");
  s.mount_rpy_rad = calib::C_bn_to_euler(g.C_bp);
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
  if (ri.setting != calib::Setting::kFactory) w.key("setting", calib::setting_name(ri.setting));
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
  if (ri.grade != calib::Grade::kNavigation || ri.min_rest_s > 0.0 || ri.prior_overrides.any()) {
    w.section("prior");
    w.key("grade", calib::grade_name(ri.grade));
    if (ri.min_rest_s > 0.0) w.key("min_rest_s", ri.min_rest_s);
    for (const EnvelopeKey& k : envelope_keys())
      if (const auto& v = ri.prior_overrides.*k.member)
        w.key(k.key, human_for_si(*v, *v / k.to_si(1.0), k.to_si));
  }
  w.section("noise");
  w.key("arw_deg_per_sqrt_h",
        human_for_si(ri.arw_rad_per_sqrt_s, ri.arw_rad_per_sqrt_s / arw_to_si(1.0), arw_to_si));
  w.key("vrw_ug_per_sqrt_hz",
        human_for_si(ri.vrw_mps_per_sqrt_s, ri.vrw_mps_per_sqrt_s / vrw_to_si(1.0), vrw_to_si));
  if (ri.dtheta_lsb_rad != calib::NoiseModel{}.dtheta_lsb_rad ||
      ri.dv_lsb_mps != calib::NoiseModel{}.dv_lsb_mps) {
    w.key("dtheta_lsb_rad", ri.dtheta_lsb_rad);
    w.key("dv_lsb_mps", ri.dv_lsb_mps);
  }
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
  ImuRowSink(calib::ImuSeries& imu, bool dv_raw_integral)
      : imu_(imu), dv_raw_integral_(dv_raw_integral) {}
  void begin(const std::vector<std::string>& columns, size_t num_rows) override {
    has_temp_ = columns.size() == 8;
    imu_.resize(num_rows);
  }
  void row(size_t k, const double* v) override {
    calib::ImuIncrement& s = imu_[k];
    s.t_s = v[0];
    s.dtheta_rad = {v[1], v[2], v[3]};
    s.dv_mps = {v[4], v[5], v[6]};
    s.temp_c = has_temp_ ? v[7] : nan_;
    // Raw integral ∫ f_b dt -> the body frame at the interval start (DESIGN §3, conventions.hpp):
    // first-order rotation compensation; sculling inside one sample is not recoverable here.
    if (dv_raw_integral_) {
      const Eigen::Vector3d v_raw = s.dv_mps;
      s.dv_mps = v_raw + 0.5 * s.dtheta_rad.cross(v_raw);
    }
  }

 private:
  calib::ImuSeries& imu_;
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
  explicit TableRowSink(std::vector<calib::TableSample>& table) : table_(table) {}
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
  std::vector<calib::TableSample>& table_;
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
    if (a.info.setting == calib::Setting::kSea)
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
  const bool field = a.info.setting != calib::Setting::kFactory;
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
      const calib::ImuIncrement& s = a.imu[k];
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
  if (ref == ReferenceKind::kNone && a.info.setting == calib::Setting::kFactory)
    throw ArchiveError(dir, "a factory run needs a reference (table or attitude log)");
  if (a.info.setting == calib::Setting::kSea && a.gnss.empty())
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

namespace {

/// The sample interval against the declared rate: catches t_s in ms or a wrong [imu] rate_hz.
void check_sample_interval(const calib::ImuSeries& imu, const RunInfo& info,
                           const std::string& imu_file) {
  const size_t n = imu.size();
  const double dt_nominal = 1.0 / info.imu_rate_hz;
  if (n < 2) return;
  std::vector<double> dts(n - 1);
  for (size_t k = 1; k < n; ++k) dts[k - 1] = imu[k].dt_s;
  std::nth_element(dts.begin(), dts.begin() + static_cast<long>(dts.size() / 2), dts.end());
  const double median = dts[dts.size() / 2];
  if (std::fabs(median - dt_nominal) > 0.05 * dt_nominal)
    throw ArchiveError(imu_file, "median sample interval " + format_double(median) +
                                     " s does not match run.toml [imu] rate_hz = " +
                                     format_double(info.imu_rate_hz) +
                                     " (1/rate = " + format_double(dt_nominal) +
                                     " s); is t_s in seconds and rate_hz right?");
}

/// Magnitude plausibility per sample, and the mean specific force at rest against gravity.
/// is_rest(k): the rest flag of sample k (the reference's, or the rest detector's).
template <typename IsRest>
void check_magnitudes(const calib::ImuSeries& imu, IsRest is_rest, const calib::Site& site,
                      const std::string& imu_file, const std::string& rest_source,
                      calib::Grade grade) {
  const double kMaxAccel_mps2 = 20.0 * kStandardGravity_mps2;
  const double kMaxRate_radps = 1000.0 * kDegToRad;
  double rest_f_sum = 0.0;
  size_t n_rest = 0;
  for (size_t k = 0; k < imu.size(); ++k) {
    const calib::ImuIncrement& s = imu[k];
    const double f = s.dv_mps.norm() / s.dt_s;
    const double w = s.dtheta_rad.norm() / s.dt_s;
    if (!(f < kMaxAccel_mps2))
      throw ArchiveError(imu_file, CsvTable::line_of_row(k),
                         "|dv|/dt = " + format_double(f) +
                             " m/s^2 exceeds 20 g (dt = " + format_double(s.dt_s) +
                             " s); dv_*_mps must be velocity increments in m/s over one sample");
    if (!(w < kMaxRate_radps))
      throw ArchiveError(imu_file, CsvTable::line_of_row(k),
                         "|dtheta|/dt = " + format_double(w * kRadToDeg) +
                             " deg/s exceeds 1000 deg/s (dt = " + format_double(s.dt_s) +
                             " s); dtheta_*_rad must be angle increments in rad over one sample");
    if (is_rest(k)) {
      rest_f_sum += f;
      ++n_rest;
    }
  }
  if (n_rest == 0) return;
  const double g = calib::EarthModel(site).gravity_mps2();
  const double f_rest = rest_f_sum / static_cast<double>(n_rest);
  // A units check (m/s per sample, not m/s²): 10 %, or as wide as the grade's own envelope lets
  // gravity read (a MEMS unit 30 % off scale is that unit; the data checks then look per rest).
  const double tol = std::max(0.1, calib::data_check_options(grade).gravity_magnitude_tol);
  if (std::fabs(f_rest - g) > tol * g)
    throw ArchiveError(
        imu_file, "mean |dv|/dt over the " + std::to_string(n_rest) + " rest samples is " +
                      format_double(f_rest) + " m/s^2 but local gravity is " + format_double(g) +
                      " m/s^2; check the dv units (m/s per sample) and the at_rest flags in " +
                      rest_source);
}

/// Land and sea: rest periods from the IMU data; the first must open the run (alignment).
calib::CalibrationInput field_input(const RunArchive& a, const std::string& imu_file) {
  calib::CalibrationInput in = calib::input_from_field_data(
      a.info.setting, a.imu,
      a.info.setting == calib::Setting::kSea ? a.gnss : std::vector<calib::GnssFix>{}, a.info.site,
      [&] {
        calib::NoiseModel nm;
        nm.arw_rad_per_sqrt_s = a.info.arw_rad_per_sqrt_s;
        nm.vrw_mps_per_sqrt_s = a.info.vrw_mps_per_sqrt_s;
        nm.dtheta_lsb_rad = a.info.dtheta_lsb_rad;
        nm.dv_lsb_mps = a.info.dv_lsb_mps;
        return nm;
      }(),
      a.info.grade, a.info.min_rest_s);
  in.prior_overrides = a.info.prior_overrides;
  const double t0 = a.imu.front().t_s;
  const double latest_start = kMaxFirstRestStart_s;
  const std::vector<calib::RestPeriod> rests = calib::find_rest_periods(in, 2);
  const calib::RestPeriod* first = rests.empty() ? nullptr : &rests.front();
  const auto span_s = [&](const calib::RestPeriod& r) {
    return a.imu[r.end - 1].t_s - a.imu[r.begin].t_s;
  };
  if (!first || a.imu[first->begin].t_s - t0 > latest_start || span_s(*first) < kMinFirstRest_s)
    throw ArchiveError(
        imu_file, std::string("no rest period at the start of this ") +
                      calib::setting_name(a.info.setting) +
                      " run: the initial alignment needs the unit standing still for at least " +
                      format_double(kMinFirstRest_s) + " s within the first " +
                      format_double(latest_start) + " s" +
                      (first ? " (the first rest found in the IMU data starts at t = " +
                                   format_double(a.imu[first->begin].t_s) + " s and lasts " +
                                   format_double(span_s(*first)) + " s)"
                             : " (no rest found in the IMU data at all)"));
  return in;
}

/// The factory reference: the attitude on the IMU time axis and the rest flag, sample by sample in
/// one pass (reserve + push_back: every page is written once, where resize() would first write
/// the default samples). Throws at the first sample whose time does not match imu.csv.
std::vector<calib::ReferenceSample> factory_reference(const RunArchive& a,
                                                      const calib::ImuSeries& imu,
                                                      const std::string& ref_file) {
  const bool table = a.info.reference == ReferenceKind::kTable;
  const calib::TableModel model(a.info.table.geometry());
  std::vector<calib::ReferenceSample> reference;
  reference.reserve(imu.size());
  // The table stands still most of the time (93 % of a factory-60 run): the same encoder angles
  // give the same C_bn bit for bit, so it is computed once per change (bits compared: -0 != +0).
  Eigen::Matrix3d C_bn;
  double C_outer = 0.0, C_inner = 0.0;
  bool have_C = false;
  auto same_bits = [](double x, double y) { return std::memcmp(&x, &y, sizeof x) == 0; };
  for (size_t k = 0; k < imu.size(); ++k) {
    const double t_ref = table ? a.table[k].t_s : a.attitude[k].t_s;
    if (!(std::fabs(t_ref - imu[k].t_s) <= kTimeMatchTolerance_s))
      throw ArchiveError(ref_file, CsvTable::line_of_row(k),
                         "t_s = " + format_double(t_ref) + " does not match imu.csv line " +
                             std::to_string(CsvTable::line_of_row(k)) +
                             " t_s = " + format_double(imu[k].t_s) +
                             " (tolerance 1 µs); the reference must be on the IMU time axis "
                             "(interpolation is not supported yet)");
    calib::ReferenceSample r;
    r.t_s = imu[k].t_s;
    if (table) {
      const calib::TableSample& s = a.table[k];
      if (!have_C || !same_bits(s.outer_rad, C_outer) || !same_bits(s.inner_rad, C_inner)) {
        C_bn = model.C_bn(s.outer_rad, s.inner_rad);
        C_outer = s.outer_rad;
        C_inner = s.inner_rad;
        have_C = true;
      }
      r.C_bn_ref = C_bn;
      r.at_rest = s.at_rest;
      r.outer_rad = s.outer_rad;
      r.inner_rad = s.inner_rad;
    } else {
      const AttitudeSample& s = a.attitude[k];
      r.C_bn_ref = calib::euler_to_C_bn(s.roll_rad, s.pitch_rad, s.yaw_rad);
      r.at_rest = s.at_rest;
    }
    reference.push_back(r);
  }
  return reference;
}

/// Factory runs: the reference on the IMU time axis, then the checks. `owned` is the archive
/// itself when the caller gave it up: its IMU series is moved into the input instead of copied
/// and its reference samples are freed as soon as the reference is built.
calib::CalibrationInput factory_input(const RunArchive& a, RunArchive* owned,
                                      const std::string& imu_file) {
  if (a.info.reference == ReferenceKind::kNone)
    throw ArchiveError(a.origin, "a factory run needs a reference (table.csv or attitude.csv)");
  const bool table = a.info.reference == ReferenceKind::kTable;
  const std::string ref_file = join_path(a.origin, table ? "table.csv" : "attitude.csv");
  const char* ref_name = table ? "table.csv" : "attitude.csv";
  const size_t n = a.imu.size();
  const size_t n_ref = table ? a.table.size() : a.attitude.size();
  if (n_ref != n)
    throw ArchiveError(ref_file,
                       std::to_string(n_ref) + " data rows but imu.csv has " + std::to_string(n) +
                           "; the reference must be logged on the IMU time axis (one row per "
                           "IMU sample; interpolation is not supported yet)");

  calib::CalibrationInput in;
  in.site = a.info.site;
  in.noise = calib::NoiseModel{};
  in.noise.arw_rad_per_sqrt_s = a.info.arw_rad_per_sqrt_s;
  in.noise.vrw_mps_per_sqrt_s = a.info.vrw_mps_per_sqrt_s;
  in.noise.dtheta_lsb_rad = a.info.dtheta_lsb_rad;
  in.noise.dv_lsb_mps = a.info.dv_lsb_mps;
  in.grade = a.info.grade;
  in.prior_overrides = a.info.prior_overrides;
  if (owned) in.imu = std::move(owned->imu);
  const calib::ImuSeries& imu = owned ? in.imu : a.imu;
  auto is_rest = [&](size_t k) { return table ? a.table[k].at_rest : a.attitude[k].at_rest; };
  // Two independent jobs, each mostly first writes to fresh memory (an hour at 100 Hz: a 37 MB
  // reference; a 26 MB copy of the series): the reference and its rest check on this thread, the
  // copy and the data checks on the other. run_concurrently reports this thread's error first,
  // which is the order of the checks one after the other.
  run_concurrently(
      [&] {
        in.reference = factory_reference(a, imu, ref_file);
        if (std::none_of(in.reference.begin(), in.reference.end(),
                         [](const calib::ReferenceSample& r) { return r.at_rest; }))
          throw ArchiveError(
              ref_file, std::string("no rest periods in ") + ref_name + ": at_rest is never 1");
      },
      [&] {
        if (!owned) in.imu = a.imu;
        check_sample_interval(imu, a.info, imu_file);
        check_magnitudes(imu, is_rest, a.info.site, imu_file, ref_name, a.info.grade);
      });
  if (owned) {  // the reference holds them now (the angles and rest flags too)
    std::vector<calib::TableSample>().swap(owned->table);
    std::vector<AttitudeSample>().swap(owned->attitude);
  }
  return in;
}

/// Both overloads; `owned` as for factory_input.
/// A unit mounted off the table's rotation centre (a fixture slot, [table] lever_arm_m): its
/// accelerometers sense the offset's kinematic acceleration while the table turns, which no method
/// models. It is the size effect with one lever arm for all three accelerometers, taken out with
/// the raw rates (the unit's scale and bias errors change it by ppm of µg).
void remove_slot_lever_arm(calib::CalibrationInput& in, const TableSetup& table) {
  if (table.lever_arm_m.isZero()) return;
  const Eigen::Vector3d r_b = table.geometry().C_bp.transpose() * table.lever_arm_m;
  calib::Effects fx;
  fx.accel_lever_arm_m = {r_b, r_b, r_b};
  calib::remove_sensor_effects(in.imu, fx, calib::ParamSet{});
}

calib::CalibrationInput convert(const RunArchive& a, RunArchive* owned) {
  const std::string imu_file = join_path(a.origin, "imu.csv");
  if (a.imu.empty()) throw ArchiveError(imu_file, "no IMU samples");
  if (!(a.info.imu_rate_hz > 0.0))
    throw ArchiveError::field_error(join_path(a.origin, "run.toml"), "imu.rate_hz", "must be > 0");
  if (a.info.setting == calib::Setting::kFactory) {
    calib::CalibrationInput in = factory_input(a, owned, imu_file);
    remove_slot_lever_arm(in, a.info.table);
    return in;
  }
  // Land and sea: calib::input_from_field_data copies the series either way.
  check_sample_interval(a.imu, a.info, imu_file);
  calib::CalibrationInput in = field_input(a, imu_file);
  check_magnitudes(
      a.imu, [&](size_t k) { return in.reference[k].at_rest; }, a.info.site, imu_file,
      "the rest periods detected in imu.csv", a.info.grade);
  return in;
}

}  // namespace

calib::CalibrationInput to_calibration_input(const RunArchive& a) { return convert(a, nullptr); }

calib::CalibrationInput to_calibration_input(RunArchive&& a) { return convert(a, &a); }

double data_span_s(const RunArchive& ar) {
  if (ar.imu.empty()) return 0.0;
  return ar.imu.back().t_s - ar.imu.front().t_s + ar.imu.front().dt_s;
}

}  // namespace imucal::archive
