#pragma once
// Shared helpers of the calibration-history tests (tests/db/repository_test.cpp, migration_test,
// crash_test, export_test) and the benchmark history_bench.cpp: a temporary directory, and
// records whose every value is derived from a seed so a test can recompute what it stored.
#include <gtest/gtest.h>
#include <stdlib.h>
#include <unistd.h>

#include <filesystem>
#include <stdexcept>
#include <string>

#include "db/history/repository.hpp"

namespace imucal::db::test {
using namespace imucal::db::history;

/// Runs f, expects it to throw E and returns the message (a test failure otherwise).
template <typename E, typename F>
std::string expect_throw_message(F f) {
  try {
    f();
  } catch (const E& e) {
    return e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << "wrong exception type: " << e.what();
    return {};
  }
  ADD_FAILURE() << "no exception";
  return {};
}

/// A fresh directory under $TMPDIR (or /tmp), removed with everything in it on destruction.
class TempDir {
 public:
  TempDir() {
    const char* base = std::getenv("TMPDIR");
    std::string templ = std::string(base && *base ? base : "/tmp") + "/imucal-db-XXXXXX";
    if (!::mkdtemp(templ.data())) throw std::runtime_error("mkdtemp failed for " + templ);
    path_ = templ;
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const std::string& path() const { return path_; }
  std::string file(const std::string& name) const { return path_ + "/" + name; }

 private:
  std::string path_;
};

/// Parameters unique to (seed, method): entry i = (seed * 1000 + 10 * method + i + 1) * 1e-7,
/// with a sign pattern, so no two stored sets coincide and values are not "round".
inline calib::core::ParamSet seeded_params(long seed, int method_index) {
  calib::core::ParamVector x;
  for (int i = 0; i < calib::core::ParamSet::kSize; ++i)
    x(i) = ((i % 3 == 1) ? -1.0 : 1.0) *
           (static_cast<double>(seed) * 1000.0 + 10.0 * method_index + i + 1) * 1.0e-7 / 3.0;
  return calib::core::ParamSet::from_vector(x);
}

inline calib::core::ParamSet seeded_sigma(long seed, int method_index) {
  return calib::core::ParamSet::from_vector(
      seeded_params(seed, method_index).to_vector().cwiseAbs() * 0.01);
}

inline CalibrationRecord seeded_calibration(long seed, Method method, bool with_metrics = true) {
  const int mi = method == Method::kAins ? 0 : 1;
  CalibrationRecord c;
  c.method = method;
  c.params = seeded_params(seed, mi);
  c.sigma = seeded_sigma(seed, mi);
  c.converged = (seed + mi) % 5 != 0;
  c.iterations = static_cast<int>(3 + seed % 7 + mi);
  c.runtime_s = 1.25 + 0.5 * mi + seed * 1e-3;
  if (seed % 4 == 0) c.warnings = {"warning one, with comma", "second \"quoted\" warning"};
  if (with_metrics) {
    StoredMetrics m;
    m.orientation_rmse_mdeg = 3.0 + seed * 0.01 + mi;
    m.accel_rmse_ug = 9.0 + seed * 0.02 + mi;
    m.heading_offset_gamma_np_rad = -1e-4 * (seed + 1);
    m.body_misalignment_theta_bp_rad = Eigen::Vector3d(1e-5, -2e-5, 3e-5) * (seed + 1 + mi);
    c.metrics = m;
  }
  return c;
}

inline NewRun new_run(const std::string& serial, TimestampMs started_at_ms,
                      RunState state = RunState::kPreparing) {
  NewRun r;
  r.serial = serial;
  r.operator_name = "op-" + std::to_string(started_at_ms % 7);
  r.station = "station-1";
  r.sequence_name = "factory-std";
  r.sequence_sha256 = std::string(64, 'a');
  r.software_version = "1.2.3-test";
  r.started_at_ms = started_at_ms;
  r.archive_path = "/var/lib/imucal/runs/" + serial + "-" + std::to_string(started_at_ms);
  r.state = state;
  return r;
}

/// A done run's completion: both methods (seeded) and a PASS cross-check.
inline RunCompletion pass_completion(long seed, TimestampMs ended_at_ms) {
  RunCompletion c;
  c.state = RunState::kDone;
  c.ended_at_ms = ended_at_ms;
  c.archive_sha256 = std::string(63, 'b') + static_cast<char>('0' + seed % 10);
  c.calibrations = {seeded_calibration(seed, Method::kAins),
                    seeded_calibration(seed, Method::kNlsq)};
  c.crosscheck = CrosscheckRecord{Verdict::kPass, 4.0, {}, {}};
  return c;
}

/// A review run's completion: both methods and a REVIEW cross-check naming one failing term.
inline RunCompletion review_completion(long seed, TimestampMs ended_at_ms) {
  RunCompletion c = pass_completion(seed, ended_at_ms);
  c.state = RunState::kReview;
  c.crosscheck = CrosscheckRecord{
      Verdict::kReview,
      4.0,
      {{"accel_bias_mps2[1]", "accel_bias_mps2[1]: |Δ| = 12.3 µg > 4σ bound 8.1 µg"}},
      {}};
  return c;
}

}  // namespace imucal::db::test
