#pragma once
// Serial numbers (station issue: "invalid serial number (allowed characters and length
// documented)"). A serial names a unit in the history database, in archive directory names and on
// the command line, so the rule keeps it safe in all three:
//
//   * 1 to 32 characters (kSerialMaxLength);
//   * only ASCII letters A-Z a-z, digits 0-9, and '-', '_', '.';
//   * the first character is a letter or a digit (so a serial is never ".", "..", a hidden file
//     name, or mistaken for a command-line option such as "-x");
//   * '-', '_' and '.' separate letters and digits: never two in a row, never last, so every part
//     of a serial holds at least one letter or digit ("sn..1", "SN-" and "SN-_1" are typing
//     slips, not serials; issue #50 item 3).
//
// Consequently no spaces, no '/', no control characters, no non-ASCII bytes. Serials are compared
// exactly (case-sensitive): "SIM-0001" and "sim-0001" are different units. A lookup that finds no
// unit says which units differ from the serial only in case ("did you mean SIM-0001?"), never
// picks one for the caller: two units may differ only in case.
//
// A database written before the separator rule may hold a serial it now refuses; such a unit's
// runs are read through the export (the whole history, no --serial).
#include <cstddef>
#include <optional>
#include <string>
#include <vector>

namespace imucal::db::history {

constexpr std::size_t kSerialMaxLength = 32;

/// The rule above in one sentence, for error messages and help texts.
extern const char* const kSerialRule;

/// nullopt if `serial` is valid, otherwise why not, e.g.
/// "serial number \"AB CD\": character ' ' at position 3 is not allowed (allowed: ...)".
std::optional<std::string> serial_problem(const std::string& serial);

/// Throws db::history::InvalidInput with serial_problem()'s message if the serial is invalid.
void validate_serial(const std::string& serial);

/// The tail of a "no unit with serial number" message naming the units that differ from the
/// asked serial only in case: "" for none, "; did you mean SN-0001? (serial numbers are compared
/// exactly, case included)", several joined by " or ".
std::string did_you_mean(const std::vector<std::string>& serials);

}  // namespace imucal::db::history
