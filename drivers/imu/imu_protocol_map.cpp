#include "drivers/imu/imu_protocol_map.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <toml++/toml.h>

#include "drivers/imu/dbc_codec.hpp"

namespace imucal::imu {

namespace {

int line_of(const toml::source_region& r) { return static_cast<int>(r.begin.line); }

/// Reads one protocol file: every error names the file and the line of the key at fault.
class MapReader {
 public:
  MapReader(std::string path, ImuProtocolMap& out) : path_(std::move(path)), m_(out) {}

  void run(const toml::table& root) {
    only_keys(root, {"protocol", "channels", "counter", "status", "check"}, "the file");
    protocol(required_table(root, "protocol"));
    channels(required_table(root, "channels"));
    counter(required_table(root, "counter"));
    if (const toml::table* s = table(root, "status", false)) status(*s);
    if (const toml::table* c = table(root, "check", false)) check(*c);
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
    m_.dbc = read_dbc(dbc.string());
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
    only_keys(t, {"angular", "velocity", "angular_scale", "velocity_scale"}, "[channels]");
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
    only_keys(t, {"fault", "saturation", "startup"}, "[status]");
    auto list = [&](const char* key, std::vector<DbcSignalRef>& out) {
      for (const auto& [name, line] : strings(t, key, false)) {
        out.push_back(ref(name, line));
        in_sample(out.back(), line);
      }
    };
    list("fault", m_.fault);
    list("saturation", m_.saturation);
    list("startup", m_.startup);
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
    in_sample({r.message, 0, spec}, line);
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
};

}  // namespace

ImuProtocolMap parse_protocol_map(const std::string& text, const std::string& path) {
  toml::table root;
  try {
    root = toml::parse(text, path);
  } catch (const toml::parse_error& e) {
    throw std::invalid_argument(path + ":" + std::to_string(e.source().begin.line) + ": " +
                                std::string(e.description()));
  }
  ImuProtocolMap m;
  m.path = path;
  MapReader(path, m).run(root);
  return m;
}

ImuProtocolMap read_protocol_map(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw std::invalid_argument(path + ": cannot read the protocol file");
  std::ostringstream os;
  os << f.rdbuf();
  return parse_protocol_map(os.str(), path);
}

}  // namespace imucal::imu
