#include "station/config/config.hpp"

#include <toml++/toml.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <vector>

#include "calib/core/conventions.hpp"
#include "calib/core/rotation.hpp"
#include "calib/effects/catalogue.hpp"
#include "db/fleet/fleet_url.hpp"
#include "db/fleet/fleet_writer.hpp"
#include "drivers/imu/imu_protocol.hpp"
#include "drivers/turntable/register_map.hpp"
#include "sequences/library.hpp"
#include "sequences/toml_support.hpp"

namespace imucal::station::config {

namespace fs = std::filesystem;

ConfigError::ConfigError(const std::string& file, int line, int column, const std::string& message)
    : std::runtime_error(file + ":" + std::to_string(line) + ":" + std::to_string(column) + ": " +
                         message),
      file_(file),
      line_(line),
      column_(column),
      message_(message) {}

double ImuSlotConfig::arw_rad_per_sqrt_s() const {
  // deg/√h -> rad/√s: 1 √h = 60 √s.
  return arw_deg_per_sqrt_h * kDegToRad / 60.0;
}
double ImuSlotConfig::vrw_mps_per_sqrt_s() const {
  // µg/√Hz is the same quantity as µg·√s; times g0 per µg gives m/s/√s.
  return vrw_ug_per_sqrt_hz * kMicroG_mps2;
}

bool is_log_level(const std::string& level) {
  static const char* const kLevels[] = {"trace", "debug",    "info", "warn",
                                        "error", "critical", "off"};
  return std::find(std::begin(kLevels), std::end(kLevels), level) != std::end(kLevels);
}

namespace {

struct Pos {
  int line = 1, column = 1;
};

Pos pos_of(const toml::source_region& r) {
  Pos p;
  if (r.begin.line > 0) {
    p.line = static_cast<int>(r.begin.line);
    p.column = std::max(1, static_cast<int>(r.begin.column));
  }
  return p;
}

std::string fmt_double(double x) {
  std::ostringstream os;
  os.precision(12);
  os << x;
  return os.str();
}

/// Reads one [section]: every access records the key, unknown keys are refused, every error names
/// "[section] key" at the key's position.
class Section {
 public:
  Section(std::string origin, std::string name, const toml::table* table, Pos header)
      : origin_(std::move(origin)), name_(std::move(name)), t_(table), header_(header) {}

  [[noreturn]] void fail(Pos p, const std::string& message) const {
    throw ConfigError(origin_, p.line, p.column, message);
  }
  [[noreturn]] void fail_key(const std::string& key, const std::string& message) const {
    fail(key_pos(key), "[" + name_ + "] " + key + ": " + message);
  }

  bool present() const { return t_ != nullptr; }
  bool has(const std::string& key) const { return t_ && t_->get(key) != nullptr; }

  Pos key_pos(const std::string& key) const {
    if (!t_) return header_;
    auto it = t_->find(key);
    return it == t_->end() ? header_ : pos_of(it->first.source());
  }

  /// Refuses keys not in `allowed`, reporting the first one in file order.
  void only(const std::vector<std::string>& allowed) const {
    if (!t_) return;
    const toml::key* first = nullptr;
    for (const auto& [k, v] : *t_) {
      if (std::find(allowed.begin(), allowed.end(), std::string(k.str())) != allowed.end())
        continue;
      if (!first || k.source().begin < first->source().begin) first = &k;
    }
    if (!first) return;
    std::string list;
    for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
    fail(pos_of(first->source()),
         "[" + name_ + "] unknown key '" + std::string(first->str()) + "' (allowed: " + list + ")");
  }

  const toml::node* node(const std::string& key, bool required) const {
    const toml::node* n = t_ ? t_->get(key) : nullptr;
    if (!n && required) {
      fail(header_, t_ ? "[" + name_ + "] missing required key '" + key + "'"
                       : "missing required key '" + key + "' (table [" + name_ + "] is missing)");
    }
    return n;
  }

  [[noreturn]] void wrong_type(const std::string& key, const toml::node& n,
                               const char* want) const {
    fail_key(key, std::string("must be ") + want + ", not " + sequences::toml_type_name(n.type()));
  }

  std::optional<double> number(const std::string& key, bool required, double lo, double hi,
                               const char* unit) const {
    const toml::node* n = node(key, required);
    if (!n) return std::nullopt;
    double x;
    if (const auto* f = n->as_floating_point()) {
      x = f->get();
    } else if (const auto* i = n->as_integer()) {
      x = static_cast<double>(i->get());
    } else {
      wrong_type(key, *n, "a number");
    }
    if (!std::isfinite(x) || x < lo || x > hi) {
      fail_key(key, fmt_double(x) + " is out of range [" + fmt_double(lo) + ", " + fmt_double(hi) +
                        "] " + unit);
    }
    return x;
  }

  std::optional<int64_t> integer(const std::string& key, bool required, int64_t lo, int64_t hi,
                                 const char* unit) const {
    const toml::node* n = node(key, required);
    if (!n) return std::nullopt;
    const auto* i = n->as_integer();
    if (!i) wrong_type(key, *n, "an integer");
    const int64_t x = i->get();
    if (x < lo || x > hi) {
      fail_key(key, std::to_string(x) + " is out of range [" + std::to_string(lo) + ", " +
                        std::to_string(hi) + "] " + unit);
    }
    return x;
  }

  std::optional<std::string> string(const std::string& key, bool required, bool allow_empty) const {
    const toml::node* n = node(key, required);
    if (!n) return std::nullopt;
    const auto* s = n->as_string();
    if (!s) wrong_type(key, *n, "a string");
    if (!allow_empty && s->get().empty()) fail_key(key, "must not be empty");
    return s->get();
  }

  /// An array of non-empty strings (an absent key: none).
  std::vector<std::string> strings(const std::string& key) const {
    const toml::node* n = node(key, false);
    if (!n) return {};
    const auto* a = n->as_array();
    if (!a) wrong_type(key, *n, "an array of strings");
    std::vector<std::string> out;
    for (const toml::node& item : *a) {
      const auto* s = item.as_string();
      if (!s)
        fail_key(key, std::string("must hold strings only, not ") +
                          sequences::toml_type_name(item.type()));
      if (s->get().empty()) fail_key(key, "must not hold an empty string");
      out.push_back(s->get());
    }
    return out;
  }

  const toml::table* sub_table(const std::string& key) const {
    const toml::node* n = node(key, false);
    if (!n) return nullptr;
    const auto* t = n->as_table();
    if (!t) wrong_type(key, *n, "a table");
    return t;
  }

  const std::string& origin() const { return origin_; }

 private:
  std::string origin_;
  std::string name_;
  const toml::table* t_;
  Pos header_;
};

std::string resolve(const std::string& base_dir, const std::string& p) {
  fs::path path(p);
  if (path.is_absolute()) return path.lexically_normal().string();
  return (fs::path(base_dir) / path).lexically_normal().string();
}

/// Finds the position of the first node (key or value) on `line` inside `t`, for errors of the
/// register map reader (which reports lines only).
std::optional<Pos> find_line(const toml::table& t, int line) {
  for (const auto& [k, v] : t) {
    if (static_cast<int>(k.source().begin.line) == line) return pos_of(k.source());
    if (const auto* sub = v.as_table()) {
      if (auto p = find_line(*sub, line)) return p;
    }
  }
  return std::nullopt;
}

/// The default sequence must exist where the daemon will look for it (a service started with
/// PrivateTmp/ProtectHome sees no source tree): a path must be a file, a name a *.toml of the
/// library — sequence_dir when configured, the daemon's lookup (sequences/library.hpp) otherwise.
void check_default_sequence(const StationConfig& c, const Section& s) {
  const std::string& v = c.default_sequence;
  std::error_code ec;
  if (v.find('/') != std::string::npos) {
    if (!fs::is_regular_file(v, ec)) s.fail_key("default_sequence", "\"" + v + "\": no such file");
    return;
  }
  const std::string dir = c.sequence_dir.empty() ? sequences::sequence_dir() : c.sequence_dir;
  const std::string stem =
      v.size() > 5 && v.compare(v.size() - 5, 5, ".toml") == 0 ? v.substr(0, v.size() - 5) : v;
  if (!stem.empty() && fs::is_regular_file(fs::path(dir) / (stem + ".toml"), ec)) return;
  std::vector<std::string> names;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec))
    if (it->path().extension() == ".toml") names.push_back(it->path().stem().string());
  std::sort(names.begin(), names.end());
  std::string list;
  for (const auto& n : names) list += (list.empty() ? "" : ", ") + n;
  s.fail_key("default_sequence", "\"" + v + "\" is not a sequence of the library " + dir +
                                     " (available: " + (list.empty() ? "none" : list) +
                                     "; set [calibration] sequence_dir)");
}

/// Top level: only the known tables, each a table.
void check_top_level(const toml::table& root, const std::string& origin) {
  const std::vector<std::string> sections = {"station", "control",     "turntable", "imu",
                                             "fleet",   "calibration", "log"};
  const toml::key* first = nullptr;
  for (const auto& [k, v] : root) {
    if (std::find(sections.begin(), sections.end(), std::string(k.str())) != sections.end()) {
      if (!v.is_table() && !(k.str() == "imu" && v.is_array_of_tables())) {
        throw ConfigError(origin, pos_of(k.source()).line, pos_of(k.source()).column,
                          "'" + std::string(k.str()) + "' must be a table ([" +
                              std::string(k.str()) + "]), not " +
                              sequences::toml_type_name(v.type()));
      }
      continue;
    }
    if (!first || k.source().begin < first->source().begin) first = &k;
  }
  if (first) {
    throw ConfigError(origin, pos_of(first->source()).line, pos_of(first->source()).column,
                      "unknown key or table '" + std::string(first->str()) +
                          "' (allowed tables: [station], [control], [turntable], [imu], "
                          "[fleet], [calibration], [log])");
  }
}

/// A section of the root (an absent one reads as empty, positioned at the file's start).
Section section_of(const toml::table& root, const std::string& origin, const std::string& name) {
  const toml::table* t = root.get_as<toml::table>(name);
  Pos header{1, 1};
  if (t) {
    auto it = root.find(name);
    header = pos_of(t->source().begin.line > 0 ? t->source() : it->first.source());
  }
  return Section(origin, name, t, header);
}

/// [station]: name, site, data directory and database.
void parse_station(const Section& s, const std::string& base_dir, StationConfig& c) {
  s.only({"name", "lat_deg", "lon_deg", "height_m", "gravity_mps2", "data_dir", "database"});
  c.station_name = *s.string("name", true, false);
  c.site.lat_rad = *s.number("lat_deg", true, -90.0, 90.0, "deg") * kDegToRad;
  c.site.lon_rad = *s.number("lon_deg", true, -180.0, 360.0, "deg") * kDegToRad;
  c.site.height_m = *s.number("height_m", true, -500.0, 9000.0, "m");
  if (auto g = s.number("gravity_mps2", false, 9.76, 9.84, "m/s^2")) c.site.gravity_mps2 = *g;
  c.data_dir = resolve(base_dir, *s.string("data_dir", true, false));
  if (auto db = s.string("database", false, false)) {
    c.database = resolve(base_dir, *db);
  } else {
    c.database = (fs::path(c.data_dir) / "history.sqlite").string();
  }
}

/// [control]: the control socket and its limits.
void parse_control(const Section& s, const std::string& base_dir, StationConfig& c) {
  s.only({"socket", "group", "socket_mode", "idle_timeout_s", "max_connections_per_user"});
  if (auto v = s.string("socket", false, false)) c.control_socket = resolve(base_dir, *v);
  if (auto v = s.string("group", false, true)) c.control_group = *v;
  if (auto v = s.integer("socket_mode", false, 0, 0777, "(octal permission bits, e.g. 0o660)"))
    c.control_socket_mode = static_cast<unsigned>(*v);
  if (auto v = s.number("idle_timeout_s", false, 1.0, 3600.0, "s")) c.control_idle_timeout_s = *v;
  if (auto v = s.integer("max_connections_per_user", false, 1, 1024, ""))
    c.control_max_connections_per_user = static_cast<std::size_t>(*v);
}

/// [turntable]: endpoint, timeouts, limits and the register map.
void parse_turntable(const Section& s, const std::string& origin, StationConfig& c) {
  s.only({"endpoint", "response_timeout_ms", "ack_timeout_ms", "poll_period_ms",
          "heartbeat_timeout_ms", "reconnect_give_up_ms", "move_timeout_s", "home_timeout_s",
          "position_tolerance_deg", "max_rate_dps", "registers"});
  auto& t = c.turntable;
  const std::string ep = *s.string("endpoint", true, false);
  try {
    t.endpoint = drivers::turntable::Endpoint::parse(ep);
  } catch (const std::exception& e) {
    s.fail_key("endpoint",
               std::string(e.what()) + " (expected \"tcp:HOST:PORT\" or \"rtu:DEVICE:BAUD:8E1\")");
  }
  using ms = std::chrono::milliseconds;
  if (auto v = s.integer("response_timeout_ms", false, 1, 60000, "ms")) t.response_timeout = ms(*v);
  if (auto v = s.integer("ack_timeout_ms", false, 1, 60000, "ms")) t.ack_timeout = ms(*v);
  if (auto v = s.integer("poll_period_ms", false, 1, 10000, "ms")) t.poll_period = ms(*v);
  if (auto v = s.integer("heartbeat_timeout_ms", false, 1, 600000, "ms"))
    t.heartbeat_timeout = ms(*v);
  if (auto v = s.integer("reconnect_give_up_ms", false, 0, 3600000, "ms"))
    t.reconnect_give_up = ms(*v);
  if (auto v = s.number("move_timeout_s", false, 0.1, 86400.0, "s")) c.move_timeout_s = *v;
  if (auto v = s.number("home_timeout_s", false, 0.1, 86400.0, "s")) c.home_timeout_s = *v;
  if (auto v = s.number("position_tolerance_deg", false, 1e-6, 10.0, "deg"))
    t.position_tolerance_deg = *v;
  if (auto v = s.number("max_rate_dps", false, 1e-3, 1000.0, "deg/s")) c.max_rate_dps = *v;
  if (const toml::table* regs = s.sub_table("registers")) {
    try {
      t.map = drivers::turntable::register_map_from_toml(*regs, origin);
    } catch (const drivers::turntable::RegisterMapError& e) {
      // The map reader names "ORIGIN:LINE: message"; add the column and the table name.
      std::string msg = e.what();
      const std::string prefix = origin + ":" + std::to_string(e.line()) + ": ";
      if (msg.rfind(prefix, 0) == 0) msg = msg.substr(prefix.size());
      Pos p = s.key_pos("registers");
      if (e.line() > 0) p = find_line(*regs, e.line()).value_or(Pos{e.line(), 1});
      throw ConfigError(origin, p.line, p.column, "[turntable.registers] " + msg);
    }
  }
}

/// A still unit's rate noise stays below this: 8 σ of one sample's rate (ARW / √dt; the magnitude
/// of three axes' noise passes 8 σ with probability 3e-13 a sample, 5 σ with 1.4e-5 — a few
/// times in a factory-std run's 2.3e5 rest samples), and never below 0.05 °/s. A
/// navigation-grade unit (2.5e-4 °/s a sample at 100 Hz) gets 0.05 °/s; a tactical one
/// (0.2 °/√h: 0.033 °/s a sample) 0.27 °/s, where 0.05 would never see it still.
double default_rest_rate_threshold_dps(const ImuSlotConfig& c) {
  const double sigma_dps = c.arw_rad_per_sqrt_s() * std::sqrt(c.rate_hz) / kDegToRad;
  return std::max(0.05, 8.0 * sigma_dps);
}

/// [imu] protocol and base_id: the unit's protocol file read and checked now (its DBC too), so
/// that a bad one stops the daemon before it starts; its errors name the file and line.
void parse_protocol(const Section& s, const std::string& base_dir, ImuSlotConfig& c) {
  std::shared_ptr<const drivers::imu::ImuProtocolMap> map;
  if (auto p = s.string("protocol", false, false)) {
    c.protocol_path = resolve(base_dir, *p);
    try {
      map = std::make_shared<const drivers::imu::ImuProtocolMap>(
          drivers::imu::read_protocol_map(c.protocol_path));
    } catch (const std::invalid_argument& e) {
      s.fail_key("protocol", e.what());
    }
  }
  if (auto v = s.integer("base_id", false, 0, 0x1FFFFFFF,
                         "(CAN id of the lowest of the sample's frames)"))
    c.base_id = static_cast<uint32_t>(*v);
  try {
    c.protocol = drivers::imu::resolve_protocol(map, c.base_id);
  } catch (const std::invalid_argument& e) {
    s.fail_key(c.base_id ? "base_id" : "protocol", e.what());
  }
}

/// A slot's name: what an operator types after --slot and what the archive records.
bool is_slot_name(const std::string& n) {
  if (n.empty() || n.size() > 16) return false;
  return std::all_of(n.begin(), n.end(), [](char ch) {
    return std::isalnum(static_cast<unsigned char>(ch)) || ch == '-' || ch == '_';
  });
}

/// A three-number array key ([x, y, z]) within ±limit.
std::optional<std::array<double, 3>> vector3(const Section& s, const toml::table* t,
                                             const std::string& key, double limit,
                                             const char* unit) {
  const toml::node* n = t ? t->get(key) : nullptr;
  if (!n) return std::nullopt;
  const auto* a = n->as_array();
  if (!a || a->size() != 3)
    s.fail_key(key, std::string("must be an array of three numbers [x, y, z] (") + unit + ")");
  std::array<double, 3> v{};
  for (size_t i = 0; i < 3; ++i) {
    const toml::node& item = *a->get(i);
    if (const auto* f = item.as_floating_point())
      v[i] = f->get();
    else if (const auto* k = item.as_integer())
      v[i] = static_cast<double>(k->get());
    else
      s.fail_key(key, std::string("must hold numbers only, not ") +
                          sequences::toml_type_name(item.type()));
    if (!std::isfinite(v[i]) || std::abs(v[i]) > limit)
      s.fail_key(key, fmt_double(v[i]) + " is out of range [-" + fmt_double(limit) + ", " +
                          fmt_double(limit) + "] " + unit);
  }
  return v;
}

/// mount_rpy_deg (ZYX Euler angles, pitch within ±90) or mount_matrix (C_bp by rows, e.g. an axis
/// permutation from the fixture's drawing: it must be a rotation, orthonormal with determinant +1).
void parse_mount(const Section& s, const toml::table* t, ImuSlotConfig& c) {
  if (s.has("mount_rpy_deg") && s.has("mount_matrix"))
    s.fail_key("mount_matrix", "give mount_rpy_deg or mount_matrix, not both");
  if (auto v = vector3(s, t, "mount_rpy_deg", 180.0, "deg")) {
    if (std::abs((*v)[1]) > 90.0)
      s.fail_key("mount_rpy_deg",
                 "pitch (second element) " + fmt_double((*v)[1]) + " deg is outside [-90, 90]");
    c.mount_rpy_deg = *v;
  }
  const toml::node* n = t ? t->get("mount_matrix") : nullptr;
  if (!n) return;
  const auto* rows = n->as_array();
  Eigen::Matrix3d C_bp;
  auto bad = [&] { s.fail_key("mount_matrix", "must be three rows of three numbers"); };
  if (!rows || rows->size() != 3) bad();
  for (size_t i = 0; i < 3; ++i) {
    const auto* row = rows->get(i)->as_array();
    if (!row || row->size() != 3) bad();
    for (size_t j = 0; j < 3; ++j) {
      const toml::node& x = *row->get(j);
      if (const auto* f = x.as_floating_point())
        C_bp(static_cast<int>(i), static_cast<int>(j)) = f->get();
      else if (const auto* k = x.as_integer())
        C_bp(static_cast<int>(i), static_cast<int>(j)) = static_cast<double>(k->get());
      else
        bad();
    }
  }
  const double off = (C_bp.transpose() * C_bp - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  if (!(off <= 1e-6))
    s.fail_key("mount_matrix", "is not a rotation: its rows are not orthonormal (|C^T C - I| = " +
                                   fmt_double(off) + ")");
  if (C_bp.determinant() < 0)
    s.fail_key("mount_matrix",
               "is not a rotation: determinant -1, a mirror image (a unit cannot be mounted so)");
  const Eigen::Vector3d rpy = calib::core::C_bn_to_euler(C_bp);
  for (int k = 0; k < 3; ++k) c.mount_rpy_deg[static_cast<size_t>(k)] = rpy(k) / kDegToRad;
}

/// [imu] / one [[imu]] entry: the slot, the CAN URI, rate, protocol, frame id, noise, the
/// capture's thresholds and the mounting.
void parse_imu(const Section& s, const toml::table* t, const std::string& base_dir,
               ImuSlotConfig& c) {
  s.only({"slot", "can", "rate_hz", "protocol", "base_id", "arw_deg_per_sqrt_h",
          "vrw_ug_per_sqrt_hz", "grade", "max_gap_samples", "settle_guard_samples",
          "rest_rate_threshold_dps", "stream_timeout_ms", "mount_rpy_deg", "mount_matrix",
          "lever_arm_m"});
  if (auto v = s.string("slot", false, false)) {
    if (!is_slot_name(*v))
      s.fail_key("slot", "\"" + *v + "\" is not a slot name (1-16 letters, digits, '-', '_')");
    c.name = *v;
  }
  parse_mount(s, t, c);
  if (auto v = vector3(s, t, "lever_arm_m", 2.0, "m")) c.lever_arm_m = *v;
  const std::string can = *s.string("can", true, false);
  const auto colon = can.find(':');
  const std::string scheme = colon == std::string::npos ? "" : can.substr(0, colon);
  const std::string rest = colon == std::string::npos ? "" : can.substr(colon + 1);
  if ((scheme != "unixcan" && scheme != "socketcan" && scheme != "candump") || rest.empty()) {
    s.fail_key("can", "\"" + can +
                          "\" is not a CAN URI (expected \"unixcan:PATH\", \"socketcan:IFACE\" "
                          "or \"candump:FILE\")");
  }
  c.can_uri = scheme == "socketcan" ? can : scheme + ":" + resolve(base_dir, rest);
  if (auto v = s.number("rate_hz", false, 1.0, 2000.0, "Hz")) c.rate_hz = *v;
  parse_protocol(s, base_dir, c);
  if (auto v = s.number("arw_deg_per_sqrt_h", false, 1e-7, 10.0, "deg/sqrt(h)"))
    c.arw_deg_per_sqrt_h = *v;
  if (auto v = s.number("vrw_ug_per_sqrt_hz", false, 1e-3, 1e5, "ug/sqrt(Hz)"))
    c.vrw_ug_per_sqrt_hz = *v;
  if (auto g = s.string("grade", false, false)) {
    const std::optional<calib::core::Grade> grade = calib::core::parse_grade(*g);
    if (!grade) s.fail_key("grade", "\"" + *g + "\" is not a grade (navigation, tactical or mems)");
    c.grade = *grade;
  }
  if (auto v = s.integer("max_gap_samples", false, 0, 100000, "samples"))
    c.max_gap_samples = static_cast<uint64_t>(*v);
  if (auto v = s.integer("settle_guard_samples", false, 0, 1000000, "samples"))
    c.settle_guard_samples = static_cast<uint64_t>(*v);
  if (auto v = s.number("rest_rate_threshold_dps", false, 1e-6, 100.0, "deg/s"))
    c.rest_rate_threshold_dps = *v;
  else
    c.rest_rate_threshold_dps = default_rest_rate_threshold_dps(c);
  if (auto v = s.integer("stream_timeout_ms", false, 10, 600000, "ms"))
    c.stream_timeout_ms = static_cast<int>(*v);
}

/// [imu] (one unit, slot "A") or [[imu]] (1 to kMaxImuSlots slots, named "A", "B", ... unless
/// they say): distinct slot names, and no two slots reading the same CAN identifiers on one bus.
void parse_imus(const toml::table& root, const std::string& origin, const std::string& base_dir,
                StationConfig& c) {
  const toml::array* list = root.get_as<toml::array>("imu");
  if (!list) {
    const Section s = section_of(root, origin, "imu");
    c.imus.emplace_back();
    parse_imu(s, root.get_as<toml::table>("imu"), base_dir, c.imus.back());
    return;
  }
  const Pos header = pos_of(root.find("imu")->first.source());
  if (list->empty() || list->size() > kMaxImuSlots)
    throw ConfigError(origin, header.line, header.column,
                      "[[imu]] must hold 1 to " + std::to_string(kMaxImuSlots) + " units, not " +
                          std::to_string(list->size()));
  for (size_t i = 0; i < list->size(); ++i) {
    const toml::table* t = list->get(i)->as_table();
    if (!t) throw ConfigError(origin, header.line, header.column, "[[imu]] entries must be tables");
    const Section s(origin, "imu", t, pos_of(t->source()));
    ImuSlotConfig slot;
    slot.name = std::string(1, static_cast<char>('A' + i));
    parse_imu(s, t, base_dir, slot);
    for (const ImuSlotConfig& other : c.imus) {
      if (other.name == slot.name) s.fail_key("slot", "\"" + slot.name + "\" is used twice");
      if (other.can_uri == slot.can_uri && other.base_id == slot.base_id)
        s.fail_key("can", "slot " + slot.name + " reads the same bus and identifiers as slot " +
                              other.name + " (give each unit its own bus or base_id)");
    }
    c.imus.push_back(std::move(slot));
  }
}

/// [calibration]: the sequence library and default, the cross-check bound, the gap false alarm.
void parse_calibration(const Section& s, const std::string& base_dir, StationConfig& c) {
  s.only({"default_sequence", "k_sigma", "gap_false_alarm", "known_effects", "sequence_dir"});
  if (auto v = s.string("sequence_dir", false, false)) {
    c.sequence_dir = resolve(base_dir, *v);
    std::error_code ec;
    if (!fs::is_directory(c.sequence_dir, ec))
      s.fail_key("sequence_dir", "\"" + c.sequence_dir + "\" is not a directory");
  }
  if (auto v = s.string("default_sequence", false, false)) {
    // A path-like value is a file next to the config; a bare name is a library sequence.
    c.default_sequence = v->find('/') != std::string::npos ? resolve(base_dir, *v) : *v;
  }
  check_default_sequence(c, s);
  if (auto v = s.number("k_sigma", false, 0.5, 100.0, "(combined standard deviations)"))
    c.k_sigma = *v;
  if (auto v = s.number("gap_false_alarm", false, 1e-9, 0.1, "(probability per run)"))
    c.gap_false_alarm = *v;
  c.known_effects = s.strings("known_effects");
  for (const std::string& name : c.known_effects)
    if (!calib::effects::find_effect(name))
      s.fail_key("known_effects", "\"" + name + "\" is not an effect of the catalogue (" +
                                      calib::effects::effect_names_list() + "; imucal effects)");
}

/// [fleet]: the fleet store (absent: none). The URL is checked by libpq's own parser and the
/// station id by the store's rule; the password is read when the sender connects (a rotated
/// password needs no restart), so an unreadable file shows in `status`, not here.
void parse_fleet(const Section& s, const toml::table* t, const std::string& base_dir,
                 StationConfig& c) {
  if (!t) return;
  s.only({"url", "station_id", "password_file", "password_env", "batch_entries"});
  FleetConfig f;
  f.url = *s.string("url", true, false);
  try {
    db::fleet::parse_fleet_target(f.url);
  } catch (const db::history::DbError& e) {
    s.fail_key("url", e.what());
  }
  f.station_id = c.station_name;
  if (auto v = s.string("station_id", false, false)) f.station_id = *v;
  try {
    db::fleet::validate_station_id(f.station_id);
  } catch (const db::history::DbError& e) {
    s.fail_key(s.has("station_id") ? "station_id" : "url",
               std::string(e.what()) + (s.has("station_id") ? "" : " (set [fleet] station_id)"));
  }
  if (auto v = s.string("password_file", false, false)) f.password_file = resolve(base_dir, *v);
  if (auto v = s.string("password_env", false, false)) f.password_env = *v;
  if (!f.password_file.empty() && !f.password_env.empty())
    s.fail_key("password_env", "give password_file or password_env, not both");
  if (auto v = s.integer("batch_entries", false, 1, 10000, ""))
    f.batch_entries = static_cast<std::size_t>(*v);
  c.fleet = f;
}

/// [log]: the log level.
void parse_log(const Section& s, StationConfig& c) {
  s.only({"level"});
  if (auto v = s.string("level", false, false)) {
    if (!is_log_level(*v)) {
      s.fail_key("level", "\"" + *v +
                              "\" is not a log level (trace, debug, info, warn, error, critical, "
                              "off)");
    }
    c.log_level = *v;
  }
}

StationConfig parse_root(const toml::table& root, const std::string& origin,
                         const std::string& base_dir) {
  check_top_level(root, origin);
  StationConfig c;
  c.imus.clear();
  c.source_path = origin;
  c.base_dir = base_dir;
  parse_station(section_of(root, origin, "station"), base_dir, c);
  parse_control(section_of(root, origin, "control"), base_dir, c);
  parse_turntable(section_of(root, origin, "turntable"), origin, c);
  parse_imus(root, origin, base_dir, c);
  parse_fleet(section_of(root, origin, "fleet"), root.get_as<toml::table>("fleet"), base_dir, c);
  parse_calibration(section_of(root, origin, "calibration"), base_dir, c);
  parse_log(section_of(root, origin, "log"), c);
  return c;
}

}  // namespace

StationConfig parse_config(std::string_view text, const std::string& origin,
                           const std::string& base_dir) {
  toml::table root;
  try {
    root = toml::parse(text, origin);
  } catch (const toml::parse_error& e) {
    const Pos p = pos_of(e.source());
    throw ConfigError(origin, p.line, p.column,
                      "TOML syntax error: " + std::string(e.description()));
  }
  std::string base = fs::absolute(base_dir.empty() ? "." : base_dir).lexically_normal().string();
  while (base.size() > 1 && base.back() == '/') base.pop_back();
  return parse_root(root, origin, base);
}

StationConfig load_config(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw ConfigError(path, 0, 0, "cannot open the configuration file");
  std::ostringstream ss;
  ss << in.rdbuf();
  if (in.bad()) throw ConfigError(path, 0, 0, "cannot read the configuration file");
  std::string base = fs::path(path).parent_path().string();
  return parse_config(ss.str(), path, base.empty() ? "." : base);
}

drivers::imu::DecoderOptions decoder_options(const ImuSlotConfig& slot) {
  drivers::imu::DecoderOptions o;
  o.protocol = slot.protocol;  // base_id applied
  o.sample_rate_hz = slot.rate_hz;
  return o;
}

const ImuSlotConfig& slot_named(const StationConfig& config, const std::string& name) {
  for (const ImuSlotConfig& slot : config.imus)
    if (slot.name == name) return slot;
  return config.imu();
}

}  // namespace imucal::station::config
