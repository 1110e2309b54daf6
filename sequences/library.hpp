#pragma once
// The shipped sequence library (sequences/*.toml) and the one-call path from a name to a
// validated motion profile.
#include <string>
#include <string_view>
#include <vector>

#include "sequences/motion_profile.hpp"
#include "sequences/validator.hpp"

namespace imucal::sequences {

/// Directory of the library, the first of: the directory set by set_sequence_dir() (stationd's
/// [calibration] sequence_dir); $IMUCAL_SEQUENCE_DIR if set and non-empty; <prefix>/share/imucal/
/// sequences next to the running program's <prefix>/bin (an installed or unpacked package); the
/// source directory compiled in, if it exists (a build tree); the install prefix's data directory
/// compiled in.
std::string sequence_dir();

/// Makes `dir` the library for this process ("" = back to the lookup above).
void set_sequence_dir(const std::string& dir);

/// Library names (file stems of *.toml in sequence_dir()), sorted.
std::vector<std::string> available_sequences();

/// "short" -> "<dir>/short.toml" (also "short.toml" -> same); an existing file path is returned
/// unchanged. Anything else throws SequenceError listing the available names.
std::string resolve_sequence(const std::string& name_or_path);

/// resolve + parse + validate (station limits tightened by the file's [limits]) + generate.
/// Throws SequenceError on the first problem.
MotionProfile load_profile(const std::string& name_or_path,
                           const TableLimits& station = TableLimits{});

/// SHA-256 of the file's bytes, lower-case hex (recorded in run.toml so a run names the exact
/// sequence it followed). Throws SequenceError if the file cannot be read.
std::string sequence_hash(const std::string& path);

/// SHA-256 (FIPS 180-4) of a byte string, lower-case hex.
std::string sha256_hex(std::string_view bytes);

}  // namespace imucal::sequences
