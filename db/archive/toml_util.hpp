#pragma once
// Strict TOML access for run.toml and unit files: every section declares its keys up front, so an
// unknown (e.g. misspelt) key is reported with its line before anything else; every wrong type,
// NaN/Inf or wrong shape is an ArchiveError with file, line and the dotted key path.
// Also a tiny TOML writer with shortest round-trip numbers.
#include <toml++/toml.h>

#include <Eigen/Core>
#include <initializer_list>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace imucal::db::archive {

/// Parse TOML text; syntax errors become ArchiveError("<file>:<line>: <description>").
toml::table parse_toml_text(const std::string& text, const std::string& file);

class TomlSection {
 public:
  /// `prefix` is the dotted path of this table ("" for the root, "station." for [station]).
  /// Throws on the first key not in `allowed`, naming it and its line.
  TomlSection(const toml::table& table, std::string file, std::string prefix,
              const std::vector<std::string_view>& allowed);

  bool has(std::string_view key) const { return table_->contains(key); }
  /// The key is present and an array (a value that may be a number or a list of them).
  bool is_array(std::string_view key) const {
    const toml::node* n = table_->get(key);
    return n && n->is_array();
  }
  /// Subsection [key]; nullopt if absent; error if present but not a table.
  std::optional<TomlSection> section(std::string_view key,
                                     const std::vector<std::string_view>& allowed) const;

  std::optional<double> number(std::string_view key) const;  ///< integer or float, finite
  double required_number(std::string_view key) const;
  std::optional<std::string> string(std::string_view key) const;
  std::optional<bool> boolean(std::string_view key) const;
  /// A string, or a TOML date-time converted to ISO 8601 text.
  std::optional<std::string> string_or_datetime(std::string_view key) const;
  std::optional<Eigen::Vector3d> vec3(std::string_view key) const;
  std::optional<Eigen::Matrix3d> mat3(std::string_view key) const;  ///< [[r0],[r1],[r2]]
  /// An array of numbers of any length.
  std::optional<std::vector<double>> numbers(std::string_view key) const;

  /// Error at this key's line (or without a line if the key is absent).
  [[noreturn]] void fail(std::string_view key, const std::string& message) const;
  std::size_t line_of(std::string_view key) const;
  std::string path(std::string_view key) const { return prefix_ + std::string(key); }
  const std::string& file() const { return file_; }

 private:
  double number_node(const toml::node& n, const std::string& field) const;
  const toml::table* table_;
  std::string file_;
  std::string prefix_;
};

/// Minimal TOML text builder (the archive writes its own TOML so numbers keep full precision).
class TomlWriter {
 public:
  void comment(std::string_view text);
  void section(std::string_view name);  ///< "[name]" preceded by a blank line
  void key(std::string_view k, double v);
  void key(std::string_view k, std::string_view v);
  void key(std::string_view k, const Eigen::Vector3d& v);
  void key(std::string_view k, const Eigen::Matrix3d& m);
  void key(std::string_view k, const std::vector<double>& v);
  const std::string& text() const { return out_; }

 private:
  std::string out_;
};

/// TOML basic-string literal with escapes.
std::string toml_quote(std::string_view s);

}  // namespace imucal::db::archive
