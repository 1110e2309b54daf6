#pragma once
// Serial numbers (station issue: "invalid serial number (allowed characters and length
// documented)"). A serial names a unit in the history database, in archive directory names and on
// the command line, so the rule keeps it safe in all three:
//
//   * 1 to 32 characters (kSerialMaxLength);
//   * only ASCII letters A-Z a-z, digits 0-9, and '-', '_', '.';
//   * the first character is a letter or a digit (so a serial is never ".", "..", a hidden file
//     name, or mistaken for a command-line option such as "-x").
//
// Consequently no spaces, no '/', no control characters, no non-ASCII bytes. Serials are compared
// exactly (case-sensitive): "SIM-0001" and "sim-0001" are different units.
#include <cstddef>
#include <optional>
#include <string>

namespace imucal::db::history {

constexpr std::size_t kSerialMaxLength = 32;

/// The rule above in one sentence, for error messages and help texts.
extern const char* const kSerialRule;

/// nullopt if `serial` is valid, otherwise why not, e.g.
/// "serial number \"AB CD\": character ' ' at position 3 is not allowed (allowed: ...)".
std::optional<std::string> serial_problem(const std::string& serial);

/// Throws db::history::InvalidInput with serial_problem()'s message if the serial is invalid.
void validate_serial(const std::string& serial);

}  // namespace imucal::db::history
