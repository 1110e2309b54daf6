#include "db/archive/toml_util.hpp"

#include <cmath>
#include <cstdio>
#include <sstream>

#include "db/archive/archive_error.hpp"
#include "db/archive/io_util.hpp"
#include "sequences/toml_support.hpp"

namespace imucal::db::archive {

namespace {

const char* type_name(const toml::node& n) { return sequences::toml_type_name(n.type()); }

std::size_t node_line(const toml::node& n) { return n.source().begin.line; }

std::string list(const std::vector<std::string_view>& keys) {
  std::string s;
  for (auto k : keys) {
    if (!s.empty()) s += ", ";
    s += k;
  }
  return s;
}

}  // namespace

toml::table parse_toml_text(const std::string& text, const std::string& file) {
  try {
    return toml::parse(text, file);
  } catch (const toml::parse_error& e) {
    throw ArchiveError(file, e.source().begin.line,
                       "TOML syntax error: " + std::string(e.description()));
  }
}

TomlSection::TomlSection(const toml::table& table, std::string file, std::string prefix,
                         const std::vector<std::string_view>& allowed)
    : table_(&table), file_(std::move(file)), prefix_(std::move(prefix)) {
  for (auto&& [k, v] : table) {
    bool ok = false;
    for (auto a : allowed) ok = ok || k.str() == a;
    if (!ok) {
      const std::string where =
          prefix_.empty() ? "at top level" : "in [" + prefix_.substr(0, prefix_.size() - 1) + "]";
      throw ArchiveError(file_, k.source().begin.line > 0 ? k.source().begin.line : node_line(v),
                         "unknown key " + where + " (allowed: " + list(allowed) + ")",
                         prefix_ + std::string(k.str()));
    }
  }
}

std::size_t TomlSection::line_of(std::string_view key) const {
  const toml::node* n = table_->get(key);
  return n ? node_line(*n) : 0;
}

void TomlSection::fail(std::string_view key, const std::string& message) const {
  throw ArchiveError(file_, line_of(key), message, path(key));
}

std::optional<TomlSection> TomlSection::section(
    std::string_view key, const std::vector<std::string_view>& allowed) const {
  const toml::node* n = table_->get(key);
  if (!n) return std::nullopt;
  if (!n->is_table())
    fail(key, std::string("expected a table [") + std::string(key) + "], got " + type_name(*n));
  return TomlSection(*n->as_table(), file_, prefix_ + std::string(key) + ".", allowed);
}

double TomlSection::number_node(const toml::node& n, const std::string& field) const {
  double v;
  if (const auto* f = n.as_floating_point()) {
    v = f->get();
  } else if (const auto* i = n.as_integer()) {
    v = static_cast<double>(i->get());
  } else {
    throw ArchiveError(file_, node_line(n), std::string("expected a number, got ") + type_name(n),
                       field);
  }
  if (!std::isfinite(v))
    throw ArchiveError(file_, node_line(n), "NaN or Inf is not allowed", field);
  return v;
}

std::optional<double> TomlSection::number(std::string_view key) const {
  const toml::node* n = table_->get(key);
  if (!n) return std::nullopt;
  return number_node(*n, path(key));
}

double TomlSection::required_number(std::string_view key) const {
  const auto v = number(key);
  if (!v) throw ArchiveError::field_error(file_, path(key), "missing (required)");
  return *v;
}

std::optional<std::string> TomlSection::string(std::string_view key) const {
  const toml::node* n = table_->get(key);
  if (!n) return std::nullopt;
  const auto* s = n->as_string();
  if (!s) fail(key, std::string("expected a string, got ") + type_name(*n));
  return s->get();
}

std::optional<bool> TomlSection::boolean(std::string_view key) const {
  const toml::node* n = table_->get(key);
  if (!n) return std::nullopt;
  const auto* b = n->as_boolean();
  if (!b) fail(key, std::string("expected true or false, got ") + type_name(*n));
  return b->get();
}

std::optional<std::string> TomlSection::string_or_datetime(std::string_view key) const {
  const toml::node* n = table_->get(key);
  if (!n) return std::nullopt;
  if (const auto* dt = n->as_date_time()) {
    std::ostringstream os;
    os << dt->get();
    return os.str();
  }
  if (!n->is_string())
    fail(key, std::string("expected an ISO 8601 date-time string, got ") + type_name(*n));
  return n->as_string()->get();
}

std::optional<Eigen::Vector3d> TomlSection::vec3(std::string_view key) const {
  const toml::node* n = table_->get(key);
  if (!n) return std::nullopt;
  const auto* a = n->as_array();
  if (!a || a->size() != 3)
    fail(key, a ? "expected 3 numbers, got " + std::to_string(a->size())
                : std::string("expected an array of 3 numbers, got ") + type_name(*n));
  Eigen::Vector3d v;
  for (int i = 0; i < 3; ++i)
    v(i) = number_node(*a->get(static_cast<size_t>(i)), path(key) + "[" + std::to_string(i) + "]");
  return v;
}

std::optional<std::vector<double>> TomlSection::numbers(std::string_view key) const {
  const toml::node* n = table_->get(key);
  if (!n) return std::nullopt;
  const auto* a = n->as_array();
  if (!a) fail(key, std::string("expected an array of numbers, got ") + type_name(*n));
  std::vector<double> v;
  for (size_t i = 0; i < a->size(); ++i)
    v.push_back(number_node(*a->get(i), path(key) + "[" + std::to_string(i) + "]"));
  return v;
}

std::optional<Eigen::Matrix3d> TomlSection::mat3(std::string_view key) const {
  const toml::node* n = table_->get(key);
  if (!n) return std::nullopt;
  const auto* a = n->as_array();
  if (!a || a->size() != 3)
    fail(key, a ? "expected 3 rows of 3 numbers, got " + std::to_string(a->size()) + " rows"
                : std::string("expected 3 rows of 3 numbers, got ") + type_name(*n));
  Eigen::Matrix3d m;
  for (int r = 0; r < 3; ++r) {
    const toml::node& rn = *a->get(static_cast<size_t>(r));
    const std::string rfield = path(key) + "[" + std::to_string(r) + "]";
    const auto* row = rn.as_array();
    if (!row || row->size() != 3)
      throw ArchiveError(file_, node_line(rn),
                         row ? "expected 3 numbers, got " + std::to_string(row->size())
                             : std::string("expected a row of 3 numbers, got ") + type_name(rn),
                         rfield);
    for (int c = 0; c < 3; ++c)
      m(r, c) =
          number_node(*row->get(static_cast<size_t>(c)), rfield + "[" + std::to_string(c) + "]");
  }
  return m;
}

std::string toml_quote(std::string_view s) {
  std::string o = "\"";
  for (char ch : s) {
    const auto c = static_cast<unsigned char>(ch);
    switch (ch) {
      case '"':
        o += "\\\"";
        break;
      case '\\':
        o += "\\\\";
        break;
      case '\n':
        o += "\\n";
        break;
      case '\t':
        o += "\\t";
        break;
      case '\r':
        o += "\\r";
        break;
      default:
        if (c < 0x20 || c == 0x7f) {
          char buf[8];
          std::snprintf(buf, sizeof buf, "\\u%04x", c);
          o += buf;
        } else {
          o += ch;
        }
    }
  }
  return o + "\"";
}

namespace {
// A TOML number that reads back bit-exactly. Integral shortest forms get ".0" so they stay floats
// (a TOML integer would lose -0.0 and overflow beyond 2^63).
std::string toml_number(std::string_view key, double v) {
  if (!std::isfinite(v))
    throw ArchiveError::field_error("<toml writer>", std::string(key), "cannot write NaN or Inf");
  std::string s = format_double(v);
  if (s.find_first_of(".e") == std::string::npos) s += ".0";
  return s;
}
}  // namespace

void TomlWriter::comment(std::string_view text) {
  out_ += "# ";
  out_ += text;
  out_ += '\n';
}

void TomlWriter::section(std::string_view name) {
  if (!out_.empty()) out_ += '\n';
  out_ += '[';
  out_ += name;
  out_ += "]\n";
}

void TomlWriter::key(std::string_view k, double v) {
  out_ += std::string(k) + " = " + toml_number(k, v) + "\n";
}

void TomlWriter::key(std::string_view k, std::string_view v) {
  out_ += std::string(k) + " = " + toml_quote(v) + "\n";
}

void TomlWriter::key(std::string_view k, const Eigen::Vector3d& v) {
  out_ += std::string(k) + " = [" + toml_number(k, v(0)) + ", " + toml_number(k, v(1)) + ", " +
          toml_number(k, v(2)) + "]\n";
}

void TomlWriter::key(std::string_view k, const std::vector<double>& v) {
  out_ += std::string(k) + " = [";
  for (size_t i = 0; i < v.size(); ++i) out_ += (i ? ", " : "") + toml_number(k, v[i]);
  out_ += "]\n";
}

void TomlWriter::key(std::string_view k, const Eigen::Matrix3d& m) {
  out_ += std::string(k) + " = [";
  for (int r = 0; r < 3; ++r) {
    out_ += r ? ", [" : "[";
    out_ += toml_number(k, m(r, 0)) + ", " + toml_number(k, m(r, 1)) + ", " +
            toml_number(k, m(r, 2)) + "]";
  }
  out_ += "]\n";
}

}  // namespace imucal::db::archive
