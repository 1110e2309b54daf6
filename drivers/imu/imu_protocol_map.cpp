#include "drivers/imu/imu_protocol_map.hpp"

#include <toml++/toml.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "drivers/imu/builtin_protocol_text.hpp"
#include "drivers/imu/dbc_codec.hpp"

namespace imucal::drivers::imu {

namespace {

int line_of(const toml::source_region& r) { return static_cast<int>(r.begin.line); }

/// Reads one protocol file: every error names the file and the line of the key at fault.
class MapReader {
 public:
  MapReader(std::string path, ImuProtocolMap& out, const std::string* dbc_text)
      : path_(std::move(path)), m_(out), dbc_text_(dbc_text) {}

  void run(const toml::table& root) {
    only_keys(root, {"protocol", "channels", "counter", "status", "check"}, "the file");
    protocol(required_table(root, "protocol"));
    channels(required_table(root, "channels"));
    counter(required_table(root, "counter"));
    if (const toml::table* s = table(root, "status", false)) status(*s);
    if (const toml::table* c = table(root, "check", false)) check(*c);
    ties(key_line(required_table(root, "counter"), "parts"));
  }

 private:
  [[noreturn]] void fail(int line, const std::string& what) const {
    throw std::invalid_argument(path_ + ":" + std::to_string(line) + ": " + what);
  }
  static int key_line(const toml::table& t, std::string_view key) {
    auto it = t.find(key);
    return it == t.end() ? line_of(t.source()) : line_of(it->first.source());
  }
  void only_keys(const toml::table& t, const std::vector<std::string>& allowed,
                 const std::string& where) const {
    for (const auto& [k, v] : t)
      if (std::find(allowed.begin(), allowed.end(), std::string(k.str())) == allowed.end()) {
        std::string list;
        for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
        fail(line_of(k.source()),
             "unknown key '" + std::string(k.str()) + "' in " + where + " (allowed: " + list + ")");
      }
  }
  const toml::table* table(const toml::table& t, const char* key, bool required) const {
    const toml::node* n = t.get(key);
    if (!n) {
      if (required) fail(line_of(t.source()), std::string("missing table [") + key + "]");
      return nullptr;
    }
    if (!n->is_table()) fail(key_line(t, key), std::string("'") + key + "' must be a table");
    return n->as_table();
  }
  const toml::table& required_table(const toml::table& t, const char* key) const {
    return *table(t, key, true);
  }
  std::string text(const toml::table& t, const char* key, const std::string& where) const {
    const toml::node* n = t.get(key);
    if (!n) fail(line_of(t.source()), "missing key '" + std::string(key) + "' in " + where);
    if (!n->is_string()) fail(key_line(t, key), "'" + std::string(key) + "' must be a string");
    return std::string(n->as_string()->get());
  }
  double number(const toml::table& t, const char* key, double fallback) const {
    const toml::node* n = t.get(key);
    if (!n) return fallback;
    const std::optional<double> v = n->value<double>();
    if (!v || !std::isfinite(*v))
      fail(key_line(t, key), "'" + std::string(key) + "' must be a number");
    return *v;
  }
  int integer(const toml::table& t, const char* key, int lo, int hi) const {
    const toml::node* n = t.get(key);
    if (!n || !n->is_integer())
      fail(n ? key_line(t, key) : line_of(t.source()),
           "'" + std::string(key) + "' must be an integer");
    const int64_t v = n->as_integer()->get();
    if (v < lo || v > hi)
      fail(key_line(t, key), "'" + std::string(key) + "' = " + std::to_string(v) +
                                 " is out of range [" + std::to_string(lo) + ", " +
                                 std::to_string(hi) + "]");
    return static_cast<int>(v);
  }
  std::vector<std::pair<std::string, int>> strings(const toml::table& t, const char* key,
                                                   bool required) const {
    std::vector<std::pair<std::string, int>> out;
    const toml::node* n = t.get(key);
    if (!n) {
      if (required) fail(line_of(t.source()), "missing key '" + std::string(key) + "'");
      return out;
    }
    const toml::array* a = n->as_array();
    if (!a) fail(key_line(t, key), "'" + std::string(key) + "' must be an array of strings");
    for (const toml::node& e : *a) {
      if (!e.is_string())
        fail(key_line(t, key), "'" + std::string(key) + "' must be an array of strings");
      out.emplace_back(std::string(e.as_string()->get()), key_line(t, key));
    }
    return out;
  }

  int position_of(int message) const {
    const auto it = std::find(m_.messages.begin(), m_.messages.end(), message);
    return it == m_.messages.end() ? -1 : static_cast<int>(it - m_.messages.begin());
  }
  int message_index(const std::string& name, int line) const {
    for (size_t i = 0; i < m_.dbc.messages.size(); ++i)
      if (m_.dbc.messages[i].name == name) return static_cast<int>(i);
    fail(line, "message '" + name + "' is not in " + m_.dbc.path);
  }
  DbcSignalRef ref(const std::string& text, int line) const {
    const size_t dot = text.find('.');
    if (dot == std::string::npos) fail(line, "'" + text + "' is no signal: write MESSAGE.SIGNAL");
    DbcSignalRef r;
    r.text = text;
    r.message = message_index(text.substr(0, dot), line);
    r.position = position_of(r.message);
    const DbcMessage& msg = m_.message(r.message);
    for (size_t i = 0; i < msg.signals.size(); ++i)
      if (msg.signals[i].name == text.substr(dot + 1)) r.signal = static_cast<int>(i);
    if (r.signal < 0)
      fail(line, "signal '" + text.substr(dot + 1) + "' is not in message " + msg.name + " of " +
                     m_.dbc.path);
    return r;
  }

  void protocol(const toml::table& t) {
    only_keys(t, {"name", "dbc", "quantity", "completes_sample", "messages"}, "[protocol]");
    m_.name = text(t, "name", "[protocol]");
    std::filesystem::path dbc = text(t, "dbc", "[protocol]");
    if (dbc.is_relative()) dbc = std::filesystem::path(path_).parent_path() / dbc;
    m_.dbc = dbc_text_ ? parse_dbc(*dbc_text_, dbc.string()) : read_dbc(dbc.string());
    const std::string q = text(t, "quantity", "[protocol]");
    if (q != "increments" && q != "rates")
      fail(key_line(t, "quantity"), "quantity '" + q + "' is not \"increments\" or \"rates\"");
    m_.quantity =
        q == "rates" ? ImuProtocolMap::Quantity::kRates : ImuProtocolMap::Quantity::kIncrements;
    for (const auto& [name, line] : strings(t, "messages", true)) {
      const int i = message_index(name, line);
      if (std::find(m_.messages.begin(), m_.messages.end(), i) != m_.messages.end())
        fail(line, "message " + name + " is listed twice in 'messages'");
      m_.messages.push_back(i);
    }
    const std::string last = text(t, "completes_sample", "[protocol]");
    m_.completes_sample = message_index(last, key_line(t, "completes_sample"));
    if (m_.messages.empty() || m_.messages.back() != m_.completes_sample)
      fail(key_line(t, "completes_sample"),
           "completes_sample " + last + " must be the last of 'messages' (it is sent last)");
  }

  void in_sample(const DbcSignalRef& r, int line) const {
    if (std::find(m_.messages.begin(), m_.messages.end(), r.message) == m_.messages.end())
      fail(line, r.text + ": message " + m_.message(r.message).name +
                     " is not among the sample's 'messages'");
  }

  void channels(const toml::table& t) {
    only_keys(t,
              {"angular", "velocity", "angular_scale", "velocity_scale", "temperature",
               "temperature_unknown"},
              "[channels]");
    auto three = [&](const char* key, std::array<DbcSignalRef, 3>& out) {
      const auto names = strings(t, key, true);
      if (names.size() != 3)
        fail(key_line(t, key), std::string("'") + key + "' needs 3 signals (x, y, z), got " +
                                   std::to_string(names.size()));
      for (size_t i = 0; i < 3; ++i) {
        out[i] = ref(names[i].first, names[i].second);
        in_sample(out[i], names[i].second);
        if (m_.signal(out[i]).multiplex_value)
          fail(names[i].second, out[i].text + " is multiplexed: a channel must be in every sample");
      }
    };
    three("angular", m_.angular);
    three("velocity", m_.velocity);
    m_.angular_scale = number(t, "angular_scale", 1.0);
    m_.velocity_scale = number(t, "velocity_scale", 1.0);
    if (m_.angular_scale == 0.0) fail(key_line(t, "angular_scale"), "angular_scale is 0");
    if (m_.velocity_scale == 0.0) fail(key_line(t, "velocity_scale"), "velocity_scale is 0");
    if (t.get("temperature")) {
      m_.temperature = ref(text(t, "temperature", "[channels]"), key_line(t, "temperature"));
      in_sample(m_.temperature, key_line(t, "temperature"));  // multiplexed: held between pages
    }
    if (const toml::node* n = t.get("temperature_unknown")) {
      if (!n->is_integer())
        fail(key_line(t, "temperature_unknown"), "'temperature_unknown' must be an integer");
      if (m_.temperature.message < 0)
        fail(key_line(t, "temperature_unknown"), "'temperature_unknown' without 'temperature'");
      m_.temperature_unknown = n->as_integer()->get();
    }
  }

  void counter(const toml::table& t) {
    only_keys(t, {"parts", "same_in"}, "[counter]");
    const toml::node* n = t.get("parts");
    const toml::array* a = n ? n->as_array() : nullptr;
    if (!a || a->empty())
      fail(n ? key_line(t, "parts") : line_of(t.source()),
           "[counter] needs 'parts' = [{ signal = \"MESSAGE.SIGNAL\", bits = n, shift = s }, ...]");
    for (const toml::node& e : *a) {
      const toml::table* p = e.as_table();
      if (!p) fail(key_line(t, "parts"), "each counter part must be an inline table");
      only_keys(*p, {"signal", "bits", "shift"}, "a counter part");
      ImuProtocolMap::CounterPart part;
      part.ref = ref(text(*p, "signal", "a counter part"), line_of(p->source()));
      in_sample(part.ref, line_of(p->source()));
      part.bits = integer(*p, "bits", 1, 32);
      part.shift = p->get("shift") ? integer(*p, "shift", 0, 31) : 0;
      const DbcSignal& s = m_.signal(part.ref);
      if (part.bits > s.length)
        fail(line_of(p->source()), "counter part " + part.ref.text + " takes " +
                                       std::to_string(part.bits) + " bits but the signal has " +
                                       std::to_string(s.length));
      m_.counter_bits = std::max(m_.counter_bits, part.shift + part.bits);
      m_.counter.push_back(part);
    }
    if (m_.counter_bits > 32) fail(key_line(t, "parts"), "the counter is wider than 32 bits");
    for (const auto& [name, line] : strings(t, "same_in", false)) {
      DbcSignalRef r = ref(name, line);
      in_sample(r, line);
      if (m_.signal(r).length < m_.counter.front().bits)
        fail(line, name + " is narrower than the counter part it copies (" +
                       std::to_string(m_.counter.front().bits) + " bits)");
      m_.same_in.push_back(std::move(r));
    }
  }

  void status(const toml::table& t) {
    only_keys(t, {"fault", "saturation", "startup", "temperature_invalid"}, "[status]");
    using C = ImuProtocolMap::Condition;
    auto list = [&](const char* key, std::vector<DbcSignalRef>& out, C condition) {
      for (const auto& [name, line] : strings(t, key, false)) {
        out.push_back(ref(name, line));
        in_sample(out.back(), line);
        m_.flags.push_back({out.back(), condition});
        if (m_.flags.size() > 32) fail(line, "more than 32 status flags");
      }
    };
    list("fault", m_.fault, C::kFault);
    list("saturation", m_.saturation, C::kSaturation);
    list("startup", m_.startup, C::kStartup);
    list("temperature_invalid", m_.temperature_invalid, C::kTemperatureInvalid);
  }

  /// Which signal ties each message's frame to its sample: the counter's low part where it is,
  /// a copy of it elsewhere. With several messages per sample, every one needs one.
  void ties(int line) {
    const ImuProtocolMap::CounterPart& low = m_.counter.front();
    if (!m_.same_in.empty() && low.shift != 0)
      fail(line, "the first counter part (" + low.ref.text +
                     ") must be the low part (shift 0) when 'same_in' copies it");
    for (const int msg : m_.messages) {
      DbcSignalRef tie;
      if (low.ref.message == msg) tie = low.ref;
      for (const DbcSignalRef& c : m_.same_in)
        if (c.message == msg) {
          if (tie.message >= 0)
            fail(line, c.text + ": message " + m_.message(msg).name +
                           " already carries the counter's low part");
          tie = c;
        }
      if (tie.message < 0 && m_.messages.size() > 1)
        fail(line, "message " + m_.message(msg).name +
                       " carries no copy of the counter's low part (add one to [counter] "
                       "same_in): its frames could not be told from another sample's");
      m_.tie.push_back(tie);
    }
  }

  void check(const toml::table& t) {
    only_keys(t, {"kind", "signal", "covers"}, "[check]");
    const std::string kind = text(t, "kind", "[check]");
    if (kind == "none") return;
    if (kind != "crc16-ccitt-false" && kind != "crc8-sae-j1850")
      fail(key_line(t, "kind"),
           "check '" + kind + "' is not none, crc16-ccitt-false or crc8-sae-j1850");
    m_.check = kind == "crc8-sae-j1850" ? ImuProtocolMap::Check::kCrc8SaeJ1850
                                        : ImuProtocolMap::Check::kCrc16CcittFalse;
    m_.check_signal = ref(text(t, "signal", "[check]"), key_line(t, "signal"));
    in_sample(m_.check_signal, key_line(t, "signal"));
    const int width = m_.check == ImuProtocolMap::Check::kCrc8SaeJ1850 ? 8 : 16;
    if (m_.signal(m_.check_signal).length != width)
      fail(key_line(t, "signal"), m_.check_signal.text + " has " +
                                      std::to_string(m_.signal(m_.check_signal).length) +
                                      " bits; " + kind + " needs " + std::to_string(width));
    for (const auto& [spec, line] : strings(t, "covers", true))
      m_.check_covers.push_back(range(spec, line));
  }

  /// "MESSAGE" or "MESSAGE:a-b"; the check's own bytes may not be covered.
  ImuProtocolMap::ByteRange range(const std::string& spec, int line) const {
    ImuProtocolMap::ByteRange r;
    const size_t colon = spec.find(':');
    r.message = message_index(spec.substr(0, colon), line);
    r.position = position_of(r.message);
    in_sample({r.message, 0, -1, spec}, line);
    const int length = m_.message(r.message).length;
    r.last = length - 1;
    if (colon != std::string::npos) {
      int a = -1, b = -1;
      char dash = 0;
      std::istringstream in(spec.substr(colon + 1));
      if (!(in >> a >> dash >> b) || dash != '-' || a < 0 || b < a || b >= length)
        fail(line,
             "'" + spec + "': bytes must be a-b within the message's " + std::to_string(length));
      r.first = a;
      r.last = b;
    }
    if (r.message == m_.check_signal.message)
      for (int bit : dbc_signal_bits(m_.signal(m_.check_signal)))
        if (bit / 8 >= r.first && bit / 8 <= r.last)
          fail(line, "'" + spec + "' covers byte " + std::to_string(bit / 8) + " of the check " +
                         m_.check_signal.text + " itself");
    return r;
  }

  std::string path_;
  ImuProtocolMap& m_;
  const std::string* dbc_text_;
};

}  // namespace

ImuProtocolMap parse_protocol_map(const std::string& text, const std::string& path,
                                  const std::string* dbc_text) {
  toml::table root;
  try {
    root = toml::parse(text, path);
  } catch (const toml::parse_error& e) {
    throw std::invalid_argument(path + ":" + std::to_string(e.source().begin.line) + ": " +
                                std::string(e.description()));
  }
  ImuProtocolMap m;
  m.path = path;
  MapReader(path, m, dbc_text).run(root);
  return m;
}

ImuProtocolMap read_protocol_map(const std::string& path) {
  return parse_protocol_map(read_small_text_file(path, "protocol file"), path);
}

std::shared_ptr<const ImuProtocolMap> builtin_protocol_map() {
  static const std::shared_ptr<const ImuProtocolMap> map = [] {
    const std::string dbc = builtin_protocol_dbc_text();
    return std::make_shared<const ImuProtocolMap>(
        parse_protocol_map(builtin_protocol_toml_text(), "(built-in) imucal-imu-1.toml", &dbc));
  }();
  return map;
}

uint32_t lowest_id(const ImuProtocolMap& map) {
  uint32_t lowest = UINT32_MAX;
  for (const int i : map.messages) lowest = std::min(lowest, map.message(i).id);
  return lowest;
}

ImuProtocolMap with_base_id(ImuProtocolMap map, uint32_t base_id) {
  const uint32_t lowest = lowest_id(map);
  for (const int i : map.messages) {
    DbcMessage& m = map.dbc.messages[static_cast<size_t>(i)];
    const uint64_t id = uint64_t{m.id} - lowest + base_id;
    const uint64_t limit = m.extended ? 0x1FFFFFFF : 0x7FF;
    if (id > limit) {
      std::ostringstream os;
      os << map.path << ": base id 0x" << std::hex << base_id << " puts message " << m.name
         << " at 0x" << id << std::dec << ", beyond the " << (m.extended ? 29 : 11) << "-bit range";
      throw std::invalid_argument(os.str());
    }
    m.id = static_cast<uint32_t>(id);
  }
  return map;
}

IncrementResolution increment_resolution(const ImuProtocolMap& map, double dt_s) {
  const double per = map.quantity == ImuProtocolMap::Quantity::kRates ? dt_s : 1.0;
  IncrementResolution r;
  for (size_t i = 0; i < 3; ++i) {
    r.dtheta_rad = std::max(r.dtheta_rad,
                            std::abs(map.signal(map.angular[i]).factor * map.angular_scale) * per);
    r.dv_mps =
        std::max(r.dv_mps, std::abs(map.signal(map.velocity[i]).factor * map.velocity_scale) * per);
  }
  return r;
}

std::string station_unsupported(const ImuProtocolMap& map) {
  if (map.messages.size() > static_cast<size_t>(kMaxSampleMessages))
    return map.path + ": a sample of " + std::to_string(map.messages.size()) +
           " messages (the station takes at most " + std::to_string(kMaxSampleMessages) + ")";
  for (const int i : map.messages) {
    const DbcMessage& m = map.message(i);
    if (m.fd || m.length > 8)
      return map.path + ": message " + m.name + " is a CAN FD frame of " +
             std::to_string(m.length) +
             " bytes; the station's CAN channel carries classic frames (up to 8 bytes)";
  }
  return "";
}

}  // namespace imucal::drivers::imu
