#pragma once
// altsim's writer of a run archive (the project's db/archive/FORMAT.md: run.toml, imu.csv,
// table.csv, truth.json), written out here so that altsim needs nothing of the project's archive
// code: the project's reader then checks altsim's files as it checks any foreign recording.
#include <string>
#include <vector>

#include "tools/altsim/alt_sim.hpp"

namespace imucal::tools::altsim {

/// What run.toml and truth.json say about the run besides the samples.
struct AltRunInfo {
  std::string serial;
  std::string software_version;
  double lat_deg = 0.0, lon_deg = 0.0, height_m = 0.0;
  double gravity_mps2 = 9.81;
  double rate_hz = 100.0;
  std::string sequence_name, sequence_sha256;
  AltTable table;  ///< geometry for [table] (C_bp must be the identity: the fixture is not written)
  AltUnit unit;    ///< truth.json: parameters, effects, noise
};

/// Writes the archive into `dir` (created; must not exist or be empty) through a temporary
/// sibling directory renamed into place, so that a reader never sees half an archive. Throws
/// std::runtime_error naming the path on any failure.
void write_alt_archive(const std::string& dir, const AltRunInfo& info,
                       const std::vector<AltSample>& samples);

}  // namespace imucal::tools::altsim
