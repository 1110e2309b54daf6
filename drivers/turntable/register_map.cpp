#include "drivers/turntable/register_map.hpp"

#include <algorithm>
#include <fstream>
#include <limits>
#include <set>
#include <sstream>
#include <tuple>
#include <vector>

namespace imucal::drivers::turntable {

bool HoldingRegisters::operator==(const HoldingRegisters& o) const {
  return std::tie(target_outer_deg, target_inner_deg, max_rate_dps, command, command_seq) ==
         std::tie(o.target_outer_deg, o.target_inner_deg, o.max_rate_dps, o.command, o.command_seq);
}
bool InputRegisters::operator==(const InputRegisters& o) const {
  return std::tie(actual_outer_deg, actual_inner_deg, rate_outer_dps, rate_inner_dps, status, fault_code,
                  heartbeat, ack_seq, ack_result) ==
         std::tie(o.actual_outer_deg, o.actual_inner_deg, o.rate_outer_dps, o.rate_inner_dps, o.status,
                  o.fault_code, o.heartbeat, o.ack_seq, o.ack_result);
}
bool StatusBits::operator==(const StatusBits& o) const {
  return std::tie(enabled, homed, moving, in_position, fault, estop) ==
         std::tie(o.enabled, o.homed, o.moving, o.in_position, o.fault, o.estop);
}
bool CommandCodes::operator==(const CommandCodes& o) const {
  return std::tie(enable, move, stop, home, clear_fault) ==
         std::tie(o.enable, o.move, o.stop, o.home, o.clear_fault);
}
bool RegisterMap::operator==(const RegisterMap& o) const {
  return unit_id == o.unit_id && word_order == o.word_order && holding == o.holding && input == o.input &&
         status_bits == o.status_bits && commands == o.commands;
}

namespace {

struct Field {
  const char* name;
  uint16_t* address;
  int width;  // registers
};

std::vector<Field> holding_fields(HoldingRegisters& h) {
  return {{"target_outer_deg", &h.target_outer_deg, 2},
          {"target_inner_deg", &h.target_inner_deg, 2},
          {"max_rate_dps", &h.max_rate_dps, 2},
          {"command", &h.command, 1},
          {"command_seq", &h.command_seq, 1}};
}

std::vector<Field> input_fields(InputRegisters& i) {
  return {{"actual_outer_deg", &i.actual_outer_deg, 2}, {"actual_inner_deg", &i.actual_inner_deg, 2},
          {"rate_outer_dps", &i.rate_outer_dps, 2},     {"rate_inner_dps", &i.rate_inner_dps, 2},
          {"status", &i.status, 1},                     {"fault_code", &i.fault_code, 1},
          {"heartbeat", &i.heartbeat, 1},               {"ack_seq", &i.ack_seq, 1},
          {"ack_result", &i.ack_result, 1}};
}

int extent_of(const std::vector<Field>& fields) {
  int end = 0;
  for (const auto& f : fields) end = std::max(end, *f.address + f.width);
  return end;
}

int line_of(const toml::source_region& r) { return static_cast<int>(r.begin.line); }

class Reader {
 public:
  explicit Reader(std::string origin) : origin_(std::move(origin)) {}

  [[noreturn]] void fail(int line, const std::string& message) const {
    throw RegisterMapError(origin_, line, message);
  }

  static int key_line(const toml::table& t, std::string_view key) {
    auto it = t.find(key);
    return it == t.end() ? line_of(t.source()) : line_of(it->first.source());
  }

  /// Rejects keys not in `allowed`, reporting the earliest offending line.
  void only_keys(const toml::table& t, const std::vector<std::string>& allowed, const std::string& where) const {
    std::vector<std::pair<int, std::string>> unknown;
    for (const auto& [k, v] : t) {
      if (std::find(allowed.begin(), allowed.end(), std::string(k.str())) == allowed.end())
        unknown.emplace_back(line_of(k.source()), std::string(k.str()));
    }
    if (unknown.empty()) return;
    std::sort(unknown.begin(), unknown.end());
    std::string list;
    for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
    fail(unknown.front().first, "unknown key '" + unknown.front().second + "' in " + where + " (allowed: " + list + ")");
  }

  const toml::table& sub_table(const toml::table& parent, const char* key, const std::string& where) const {
    const toml::node* n = parent.get(key);
    if (!n) fail(line_of(parent.source()), "missing required table '" + std::string(key) + "' in " + where);
    const toml::table* t = n->as_table();
    if (!t) fail(key_line(parent, key), "'" + std::string(key) + "' in " + where + " must be a table");
    return *t;
  }

  int64_t integer(const toml::table& t, const char* key, const std::string& where, int64_t lo, int64_t hi) const {
    const toml::node* n = t.get(key);
    if (!n) fail(line_of(t.source()), "missing required key '" + std::string(key) + "' in " + where);
    const auto* v = n->as_integer();
    if (!v) fail(key_line(t, key), "'" + std::string(key) + "' in " + where + " must be an integer");
    const int64_t x = v->get();
    if (x < lo || x > hi)
      fail(key_line(t, key), "'" + std::string(key) + "' in " + where + " = " + std::to_string(x) +
                                 " is out of range [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
    return x;
  }

  /// Reads the addresses of one register space and rejects overlaps.
  void addresses(const toml::table& t, std::vector<Field> fields, const std::string& where) const {
    std::vector<std::string> names;
    for (const auto& f : fields) names.emplace_back(f.name);
    only_keys(t, names, where);
    struct Span {
      int start, end, line;
      const char* name;
    };
    std::vector<Span> spans;
    for (auto& f : fields) {
      *f.address = static_cast<uint16_t>(integer(t, f.name, where, 0, 65536 - f.width));
      spans.push_back({*f.address, *f.address + f.width, key_line(t, f.name), f.name});
    }
    for (size_t i = 0; i < spans.size(); ++i) {
      for (size_t j = 0; j < i; ++j) {
        const Span& a = spans[i];
        const Span& b = spans[j];
        if (a.start < b.end && b.start < a.end) {
          const Span& later = a.line >= b.line ? a : b;
          const Span& other = a.line >= b.line ? b : a;
          fail(later.line, std::string("register '") + later.name + "' [" + std::to_string(later.start) + ", " +
                               std::to_string(later.end - 1) + "] overlaps '" + other.name + "' [" +
                               std::to_string(other.start) + ", " + std::to_string(other.end - 1) + "] in " + where);
        }
      }
    }
  }

 private:
  std::string origin_;
};

}  // namespace

int RegisterMap::holding_extent() const {
  HoldingRegisters h = holding;
  return extent_of(holding_fields(h));
}
int RegisterMap::input_extent() const {
  InputRegisters i = input;
  return extent_of(input_fields(i));
}
uint16_t RegisterMap::input_first() const {
  InputRegisters i = input;
  uint16_t first = std::numeric_limits<uint16_t>::max();
  for (const auto& f : input_fields(i)) first = std::min(first, *f.address);
  return first;
}

RegisterMapError::RegisterMapError(const std::string& origin, int line, const std::string& message)
    : std::runtime_error(origin + ":" + std::to_string(line) + ": " + message), line_(line) {}

RegisterMap default_register_map() { return RegisterMap{}; }

RegisterMap register_map_from_toml(const toml::table& t, const std::string& origin) {
  Reader r(origin);
  RegisterMap m;
  const std::string where = "[register_map]";
  r.only_keys(t, {"unit_id", "word_order", "holding", "input", "status_bits", "commands"}, where);

  m.unit_id = static_cast<uint8_t>(r.integer(t, "unit_id", where, 0, 255));

  const toml::node* wo = t.get("word_order");
  if (!wo) r.fail(line_of(t.source()), "missing required key 'word_order' in " + where);
  const auto* wo_str = wo->as_string();
  const auto order = wo_str ? parse_word_order(wo_str->get()) : std::nullopt;
  if (!order)
    r.fail(Reader::key_line(t, "word_order"),
           "'word_order' in " + where + " must be one of \"ABCD\" (high word first), \"CDAB\" (low word first), "
           "\"BADC\", \"DCBA\"");
  m.word_order = *order;

  const std::string wh = "[register_map.holding]";
  const toml::table& holding = r.sub_table(t, "holding", where);
  r.addresses(holding, holding_fields(m.holding), wh);
  if (m.holding.command_seq != m.holding.command + 1)
    r.fail(Reader::key_line(holding, "command_seq"),
           "'command_seq' in " + wh + " must directly follow 'command' (command + 1 = " +
               std::to_string(m.holding.command + 1) + ") so both are written in one request");

  r.addresses(r.sub_table(t, "input", where), input_fields(m.input), "[register_map.input]");

  const std::string ws = "[register_map.status_bits]";
  const toml::table& bits = r.sub_table(t, "status_bits", where);
  r.only_keys(bits, {"enabled", "homed", "moving", "in_position", "fault", "estop"}, ws);
  std::vector<std::pair<const char*, uint8_t*>> bit_fields = {
      {"enabled", &m.status_bits.enabled}, {"homed", &m.status_bits.homed},
      {"moving", &m.status_bits.moving},   {"in_position", &m.status_bits.in_position},
      {"fault", &m.status_bits.fault},     {"estop", &m.status_bits.estop}};
  std::vector<std::pair<int, const char*>> seen_bits(16, {0, nullptr});
  for (auto& [name, out] : bit_fields) {
    *out = static_cast<uint8_t>(r.integer(bits, name, ws, 0, 15));
    if (seen_bits[*out].second)
      r.fail(Reader::key_line(bits, name), std::string("status bit '") + name + "' = " + std::to_string(*out) +
                                               " is already used by '" + seen_bits[*out].second + "' in " + ws);
    seen_bits[*out] = {Reader::key_line(bits, name), name};
  }

  const std::string wc = "[register_map.commands]";
  const toml::table& cmds = r.sub_table(t, "commands", where);
  r.only_keys(cmds, {"enable", "move", "stop", "home", "clear_fault"}, wc);
  std::vector<std::pair<const char*, uint16_t*>> cmd_fields = {{"enable", &m.commands.enable},
                                                               {"move", &m.commands.move},
                                                               {"stop", &m.commands.stop},
                                                               {"home", &m.commands.home},
                                                               {"clear_fault", &m.commands.clear_fault}};
  std::vector<std::pair<uint16_t, const char*>> seen_codes;
  for (auto& [name, out] : cmd_fields) {
    *out = static_cast<uint16_t>(r.integer(cmds, name, wc, 1, 65535));
    for (const auto& [code, other] : seen_codes)
      if (code == *out)
        r.fail(Reader::key_line(cmds, name), std::string("command code '") + name + "' = " + std::to_string(*out) +
                                                 " is already used by '" + other + "' in " + wc);
    seen_codes.emplace_back(*out, name);
  }
  return m;
}

RegisterMap parse_register_map(std::string_view toml_text, const std::string& origin) {
  toml::table root;
  try {
    root = toml::parse(toml_text, origin);
  } catch (const toml::parse_error& e) {
    throw RegisterMapError(origin, line_of(e.source()), "TOML syntax error: " + std::string(e.description()));
  }
  const toml::node* n = root.get("register_map");
  if (!n) throw RegisterMapError(origin, 1, "missing required table [register_map]");
  const toml::table* t = n->as_table();
  if (!t) throw RegisterMapError(origin, line_of(n->source()), "'register_map' must be a table");
  return register_map_from_toml(*t, origin);
}

RegisterMap load_register_map(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw RegisterMapError(path, 0, "cannot open register map file");
  std::ostringstream ss;
  ss << in.rdbuf();
  return parse_register_map(ss.str(), path);
}

std::string describe(const RegisterMap& m) {
  std::ostringstream s;
  s << "unit " << int(m.unit_id) << ", floats " << to_string(m.word_order) << ", holding: target_outer@"
    << m.holding.target_outer_deg << " target_inner@" << m.holding.target_inner_deg << " max_rate@"
    << m.holding.max_rate_dps << " command@" << m.holding.command << "+seq@" << m.holding.command_seq
    << "; input: outer@" << m.input.actual_outer_deg << " inner@" << m.input.actual_inner_deg << " rates@"
    << m.input.rate_outer_dps << "," << m.input.rate_inner_dps << " status@" << m.input.status << " fault@"
    << m.input.fault_code << " heartbeat@" << m.input.heartbeat << " ack@" << m.input.ack_seq << ","
    << m.input.ack_result;
  return s.str();
}

}  // namespace imucal::drivers::turntable
