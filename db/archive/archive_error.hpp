#pragma once
// The one exception type of the run-archive boundary (ARCHITECTURE §5). Data from other stations
// and simulators enter here, so every error names the file and the line and/or field a user must
// fix.
//   what() = "<file>:<line>: <message>"                    (line known)
//          | "<file>: field '<name>': <message>"           (field known)
//          | "<file>:<line>: field '<name>': <message>"    (both known, e.g. a TOML key)
//          | "<file>:<line>: column '<name>': <message>"   (CSV cell)
//          | "<file>: <message>"                           (whole-file problems)
#include <cstddef>
#include <stdexcept>
#include <string>
#include <utility>

namespace imucal::db::archive {

class ArchiveError : public std::runtime_error {
 public:
  /// Error at a line (1-based; 0 = no line) of a file, optionally naming a field/column.
  ArchiveError(std::string file, std::size_t line, std::string message, std::string field = {})
      : ArchiveError(std::move(file), line, std::move(message), std::move(field), "field") {}

  /// Error about a whole file (no line, no field).
  ArchiveError(std::string file, std::string message)
      : ArchiveError(std::move(file), 0, std::move(message)) {}

  /// Error about a named field of a file (JSON/TOML key path), without a line.
  static ArchiveError field_error(std::string file, std::string field, std::string message) {
    return ArchiveError(std::move(file), 0, std::move(message), std::move(field));
  }

  /// Error in one CSV cell: field() is the column name.
  static ArchiveError column_error(std::string file, std::size_t line, std::string column,
                                   std::string message) {
    return ArchiveError(std::move(file), line, std::move(message), std::move(column), "column");
  }

  const std::string& file() const { return file_; }
  std::size_t line() const { return line_; }           ///< 0 if unknown
  const std::string& field() const { return field_; }  ///< empty if none
  const std::string& message() const { return message_; }

 private:
  ArchiveError(std::string file, std::size_t line, std::string message, std::string field,
               const char* field_label)
      : std::runtime_error(format(file, line, field, field_label, message)),
        file_(std::move(file)),
        line_(line),
        field_(std::move(field)),
        message_(std::move(message)) {}

  static std::string format(const std::string& file, std::size_t line, const std::string& field,
                            const char* field_label, const std::string& message) {
    std::string s = file;
    if (line > 0) s += ":" + std::to_string(line);
    s += ": ";
    if (!field.empty()) s += std::string(field_label) + " '" + field + "': ";
    s += message;
    return s;
  }

  std::string file_;
  std::size_t line_;
  std::string field_;
  std::string message_;
};

}  // namespace imucal::db::archive
