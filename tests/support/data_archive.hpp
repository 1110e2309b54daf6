#pragma once
// A run archive kept as tests/data/NAME.tar.xz (one top directory NAME), unpacked for one test.
#include <cstdlib>
#include <stdexcept>
#include <string>

namespace imucal::test_support {

/// Unpacks tests/data/`name`.tar.xz into `dir`; returns the path of its directory `dir`/`name`.
inline std::string unpack_data_archive(const std::string& name, const std::string& dir) {
  const std::string cmd = std::string("tar -xJf '") + IMUCAL_SOURCE_DIR + "/tests/data/" + name +
                          ".tar.xz' -C '" + dir + "'";
  if (std::system(cmd.c_str()) != 0) throw std::runtime_error("cannot unpack: " + cmd);
  return dir + "/" + name;
}

}  // namespace imucal::test_support
