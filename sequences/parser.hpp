#pragma once
// Reads a rotation-sequence TOML file (format: sequences/FORMAT.md) into a Sequence.
// The parser checks syntax and schema (known keys, types, required keys, signs, finiteness);
// table limits and calibration rules are the validator's job (validator.hpp).
#include <string>

#include "sequences/sequence.hpp"
#include "sequences/sequence_error.hpp"

namespace imucal::sequences {

/// Parses the file at path. Throws SequenceError ("<path>:<line>: <message>") on any problem,
/// including a file that cannot be read.
Sequence parse_sequence_file(const std::string& path);

/// Parses TOML text; origin names the text in error messages and becomes Sequence::source_path.
Sequence parse_sequence_string(const std::string& text, const std::string& origin);

}  // namespace imucal::sequences
