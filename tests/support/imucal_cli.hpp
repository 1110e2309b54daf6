#pragma once
// Helpers of the tests that drive the real `imucal` binary on archive directories: run it, read a
// file, and list a directory (name and size of every file) to prove that nothing was written.
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "tests/support/run_command.hpp"

namespace imucal::test_support {

/// `imucal ARGS`, stderr merged into the output unless merge_stderr is false (then discarded).
inline CommandResult run_imucal(const std::string& args, bool merge_stderr = true) {
  return run_command(std::string(IMUCAL_BIN_DIR) + "/imucal " + args +
                     (merge_stderr ? " 2>&1" : " 2>/dev/null"));
}

inline std::string slurp(const std::filesystem::path& p) {
  std::ifstream f(p);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

/// "name:size" of every entry of `dir`, one per line.
inline std::string listing(const std::filesystem::path& dir) {
  std::string s;
  for (const auto& e : std::filesystem::directory_iterator(dir))
    s += e.path().filename().string() + ":" + std::to_string(std::filesystem::file_size(e.path())) +
         "\n";
  return s;
}

}  // namespace imucal::test_support
