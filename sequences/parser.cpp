#include "sequences/toml_support.hpp"
#include "sequences/parser.hpp"

#include <toml++/toml.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <initializer_list>
#include <sstream>
#include <utility>
#include <vector>

namespace imucal::sequences {
namespace {

// Defaults applied when [defaults] omits a key (documented in FORMAT.md).
constexpr double kDefaultRateDps = 10.0;
constexpr double kDefaultAccelDps2 = 10.0;

const char* type_name(toml::node_type t) { return toml_type_name(t); }

int line_of(const toml::source_region& r) { return static_cast<int>(r.begin.line); }

std::string join(std::initializer_list<const char*> names) {
  std::string s;
  for (const char* n : names) {
    if (!s.empty()) s += ", ";
    s += n;
  }
  return s;
}

/// Sign constraint of a numeric key.
enum class Sign { kAny, kPositive };

class Parser {
 public:
  explicit Parser(std::string origin) : origin_(std::move(origin)) {}

  Sequence run(const std::string& text) {
    toml::table root;
    try {
      root = toml::parse(std::string_view(text), std::string_view(origin_));
    } catch (const toml::parse_error& e) {
      fail(line_of(e.source()), "TOML syntax error: " + std::string(e.description()));
    }

    Sequence seq;
    seq.source_path = origin_;
    reject_unknown_keys(root, {"name", "description", "start", "defaults", "limits", "step"},
                        "the top level");

    seq.name = required_string(root, "name", "the top level", 0);
    if (seq.name.empty()) fail(key_line(root, "name"), "'name' must not be empty");
    if (root.contains("description"))
      seq.description = required_string(root, "description", "the top level", 0);

    const toml::table* start = table_or_null(root, "start");
    if (!start) fail(0, "missing required table [start] (start angles and initial rest_s)");
    parse_start(*start, seq.start);

    if (const toml::table* defaults = table_or_null(root, "defaults")) parse_defaults(*defaults);
    if (const toml::table* limits = table_or_null(root, "limits"))
      parse_limits(*limits, seq.limits);

    parse_steps(root, seq.steps);
    return seq;
  }

 private:
  [[noreturn]] void fail(int line, const std::string& message) const {
    throw SequenceError(origin_, line, message);
  }

  static int key_line(const toml::table& t, const char* key) {
    auto it = t.find(key);
    return it == t.end() ? line_of(t.source()) : line_of(it->first.source());
  }

  /// Unknown keys are rejected (a typo like "rate_dsp" must not silently fall back to a
  /// default). The earliest offending line is reported, whatever the map's key order.
  void reject_unknown_keys(const toml::table& t, std::initializer_list<const char*> allowed,
                           const std::string& where) const {
    std::vector<std::pair<int, std::string>> unknown;
    for (const auto& entry : t) {
      // A named reference: a lambda may not capture a structured binding in C++17.
      const toml::key& k = entry.first;
      const bool ok =
          std::any_of(allowed.begin(), allowed.end(), [&](const char* a) { return k.str() == a; });
      if (!ok) unknown.emplace_back(line_of(k.source()), std::string(k.str()));
    }
    if (unknown.empty()) return;
    std::sort(unknown.begin(), unknown.end());
    fail(unknown.front().first, "unknown key '" + unknown.front().second + "' in " + where +
                                    " (allowed: " + join(allowed) + ")");
  }

  const toml::table* table_or_null(const toml::table& parent, const char* key) const {
    const toml::node* n = parent.get(key);
    if (!n) return nullptr;
    if (!n->is_table())
      fail(key_line(parent, key),
           "'" + std::string(key) + "' must be a table, got " + type_name(n->type()));
    return n->as_table();
  }

  std::string required_string(const toml::table& t, const char* key, const std::string& where,
                              int line_if_missing) const {
    const toml::node* n = t.get(key);
    if (!n) fail(line_if_missing, "missing required key '" + std::string(key) + "' in " + where);
    if (!n->is_string())
      fail(key_line(t, key), "'" + std::string(key) + "' in " + where + " must be a string, got " +
                                 type_name(n->type()));
    return n->as_string()->get();
  }

  /// Reads an optional number (integer or float). Returns false if absent; *line gets the key line.
  bool number(const toml::table& t, const char* key, const std::string& where, Sign sign,
              double* out, int* line) const {
    const toml::node* n = t.get(key);
    if (!n) return false;
    const int l = key_line(t, key);
    double v = 0.0;
    if (n->is_integer()) {
      v = static_cast<double>(n->as_integer()->get());
    } else if (n->is_floating_point()) {
      v = n->as_floating_point()->get();
    } else {
      fail(l, "'" + std::string(key) + "' in " + where + " must be a number, got " +
                  type_name(n->type()));
    }
    if (!std::isfinite(v))
      fail(l, "'" + std::string(key) + "' in " + where + " must be finite, got " +
                  (std::isnan(v) ? "nan" : "inf"));
    if (sign == Sign::kPositive && !(v > 0.0)) {
      std::ostringstream os;
      os << "'" << key << "' in " << where << " must be > 0, got " << v;
      fail(l, os.str());
    }
    *out = v;
    if (line) *line = l;
    return true;
  }

  void parse_start(const toml::table& t, Start& s) const {
    const std::string where = "[start]";
    reject_unknown_keys(t, {"outer_deg", "inner_deg", "rest_s"}, where);
    s.line = line_of(t.source());
    number(t, "outer_deg", where, Sign::kAny, &s.outer_deg, nullptr);
    number(t, "inner_deg", where, Sign::kAny, &s.inner_deg, nullptr);
    if (!number(t, "rest_s", where, Sign::kPositive, &s.rest_s, &s.rest_line))
      fail(s.line, "missing required key 'rest_s' in [start] (initial rest period, s)");
  }

  void parse_defaults(const toml::table& t) {
    const std::string where = "[defaults]";
    reject_unknown_keys(t, {"rate_dps", "accel_dps2"}, where);
    number(t, "rate_dps", where, Sign::kPositive, &default_rate_dps_, &default_rate_line_);
    number(t, "accel_dps2", where, Sign::kPositive, &default_accel_dps2_, &default_accel_line_);
  }

  void parse_limits(const toml::table& t, DeclaredLimits& lim) const {
    const std::string where = "[limits]";
    reject_unknown_keys(t,
                        {"max_rate_dps", "max_accel_dps2", "min_rest_s", "max_duration_s",
                         "inner_min_deg", "inner_max_deg", "outer_min_deg", "outer_max_deg"},
                        where);
    lim.line = line_of(t.source());
    auto opt = [&](const char* key, Sign sign, std::optional<double>& dst) {
      double v = 0.0;
      if (number(t, key, where, sign, &v, nullptr)) dst = v;
    };
    opt("max_rate_dps", Sign::kPositive, lim.max_rate_dps);
    opt("max_accel_dps2", Sign::kPositive, lim.max_accel_dps2);
    opt("min_rest_s", Sign::kPositive, lim.min_rest_s);
    opt("max_duration_s", Sign::kPositive, lim.max_duration_s);
    opt("inner_min_deg", Sign::kAny, lim.inner_min_deg);
    opt("inner_max_deg", Sign::kAny, lim.inner_max_deg);
    opt("outer_min_deg", Sign::kAny, lim.outer_min_deg);
    opt("outer_max_deg", Sign::kAny, lim.outer_max_deg);
    if (lim.inner_min_deg && lim.inner_max_deg && !(*lim.inner_min_deg < *lim.inner_max_deg))
      fail(key_line(t, "inner_max_deg"), "inner_max_deg must be greater than inner_min_deg");
    if (lim.outer_min_deg && lim.outer_max_deg && !(*lim.outer_min_deg < *lim.outer_max_deg))
      fail(key_line(t, "outer_max_deg"), "outer_max_deg must be greater than outer_min_deg");
  }

  void parse_steps(const toml::table& root, std::vector<Step>& steps) const {
    const toml::node* n = root.get("step");
    if (!n) fail(0, "missing [[step]] entries: a sequence needs at least one step");
    const int array_line = key_line(root, "step");
    if (!n->is_array())
      fail(array_line, "'step' must be an array of tables ([[step]]), got " +
                           std::string(type_name(n->type())));
    const toml::array& arr = *n->as_array();
    if (arr.empty()) fail(array_line, "'step' is empty: a sequence needs at least one step");
    for (size_t i = 0; i < arr.size(); ++i) {
      const toml::node& e = arr[i];
      const std::string where = "[[step]] #" + std::to_string(i + 1);
      if (!e.is_table())
        fail(line_of(e.source()), where + " must be a table, got " + type_name(e.type()));
      steps.push_back(parse_step(*e.as_table(), where));
    }
  }

  Step parse_step(const toml::table& t, const std::string& where) const {
    reject_unknown_keys(t, {"rotate", "by_deg", "to_deg", "rate_dps", "accel_dps2", "rest_s"},
                        where);
    Step s;
    s.line = line_of(t.source());
    const bool has_rotate = t.contains("rotate");
    const bool has_rest = t.contains("rest_s");
    if (has_rotate && has_rest)
      fail(s.line, where + " has both 'rotate' and 'rest_s'; put the rest in its own [[step]]");
    if (!has_rotate && !has_rest)
      fail(s.line, where + " has no action: expected rotate = \"outer\"|\"inner\" or rest_s");

    if (has_rest) {
      s.kind = StepKind::kRest;
      for (const char* k : {"by_deg", "to_deg", "rate_dps", "accel_dps2"})
        if (t.contains(k))
          fail(key_line(t, k),
               "'" + std::string(k) + "' is not allowed in a rest step (" + where + ")");
      number(t, "rest_s", where, Sign::kPositive, &s.duration_s, &s.value_line);
      return s;
    }

    s.kind = StepKind::kRotate;
    const std::string axis = required_string(t, "rotate", where, s.line);
    if (axis == "outer") {
      s.axis = Axis::kOuter;
    } else if (axis == "inner") {
      s.axis = Axis::kInner;
    } else {
      fail(key_line(t, "rotate"),
           "unknown axis '" + axis + "' in " + where + " (expected \"outer\" or \"inner\")");
    }
    const bool has_by = t.contains("by_deg");
    const bool has_to = t.contains("to_deg");
    if (has_by && has_to)
      fail(std::max(key_line(t, "by_deg"), key_line(t, "to_deg")),
           where + " has both 'by_deg' and 'to_deg'; give exactly one");
    if (!has_by && !has_to)
      fail(s.line, where + " rotates but gives neither 'by_deg' nor 'to_deg'");
    double v = 0.0;
    if (has_by) {
      number(t, "by_deg", where, Sign::kAny, &v, &s.value_line);
      s.by_deg = v;
    } else {
      number(t, "to_deg", where, Sign::kAny, &v, &s.value_line);
      s.to_deg = v;
    }
    s.rate_dps = default_rate_dps_;
    s.rate_line = default_rate_line_ ? default_rate_line_ : s.line;
    number(t, "rate_dps", where, Sign::kPositive, &s.rate_dps, &s.rate_line);
    s.accel_dps2 = default_accel_dps2_;
    s.accel_line = default_accel_line_ ? default_accel_line_ : s.line;
    number(t, "accel_dps2", where, Sign::kPositive, &s.accel_dps2, &s.accel_line);
    return s;
  }

  std::string origin_;
  double default_rate_dps_ = kDefaultRateDps;
  double default_accel_dps2_ = kDefaultAccelDps2;
  int default_rate_line_ = 0;
  int default_accel_line_ = 0;
};

}  // namespace

Sequence parse_sequence_string(const std::string& text, const std::string& origin) {
  return Parser(origin).run(text);
}

Sequence parse_sequence_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in)
    throw SequenceError(path, 0, std::string("cannot open sequence file: ") + std::strerror(errno));
  std::ostringstream buf;
  buf << in.rdbuf();
  if (in.bad()) throw SequenceError(path, 0, "error while reading sequence file");
  return parse_sequence_string(buf.str(), path);
}

}  // namespace imucal::sequences
