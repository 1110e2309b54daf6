// The direct JSON row writer of the export (db/history/export_row_writer.hpp) against nlohmann's
// dump of the same row built from the public record functions (run_json, calibration_json,
// crosscheck_json): byte for byte on hand-picked rows (every optional present and absent,
// strings that need escaping, numbers nlohmann prints in its own way) and on random ones, and the
// same errors for what cannot be written.
#include "db/history/export_row_writer.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <string>

#include "db/history/export.hpp"

namespace imucal::db {
using namespace imucal::db::history;
namespace {

/// What the export printed before the direct writer: the nlohmann object, dumped compactly.
std::string reference(const ExportRow& row) {
  nlohmann::json o = run_json(row.run);
  o["calibration"] = row.calibration ? calibration_json(*row.calibration) : nullptr;
  o["crosscheck"] = row.crosscheck ? crosscheck_json(*row.crosscheck) : nullptr;
  return o.dump();
}

std::string direct(const ExportRow& row) {
  std::string s = "prefix:";
  append_export_row_json(s, row);
  EXPECT_EQ(s.rfind("prefix:", 0), 0u) << "the writer must append, not replace";
  return s.substr(7);
}

calib::core::ParamSet params_from(double base) {
  calib::core::ParamVector v;
  for (int i = 0; i < calib::core::ParamSet::kSize; ++i)
    v(i) = base * (i + 1) * (i % 2 ? -1.0 : 1.0);
  return calib::core::ParamSet::from_vector(v);
}

ExportRow full_row() {
  ExportRow row;
  RunRecord& r = row.run;
  r.run_id = 123456789012;
  r.serial = "SN-0042";
  r.operator_name = "Zoë \"Z\" O'Brien\\ops";
  r.station = "line\t3\nbay 2";
  r.sequence_name = "factory-std";
  r.sequence_sha256 = std::string(64, 'a');
  r.software_version = "0.1.0";
  r.started_at_ms = 1764115200123;
  r.ended_at_ms = 1764117480456;
  r.state = RunState::kDone;
  r.failure_reason = std::string("ctl\x01\x1f del\x7f");
  r.archive_path = "/var/lib/imucal/runs/SN-0042/2026-11-26T00-00-00Z";
  r.archive_sha256 = std::string(64, 'f');
  r.reprocessed_from = 7;
  r.verdict = RunVerdict::kReview;
  r.crosscheck_verdict = Verdict::kPass;
  r.reasons = {{"gap", "sim-to-real gap: \"K2\"; ±1e-7"}, {"limits", "ctl\x01 del\x7f"}};
  r.capture_json =
      R"({ "frames_received" : 359700, "crc_errors":0, "nested": {"b":1.5,"a":[1,2]} })";
  r.diagnosis_json = R"({"verdict":"PASS","gap":1e-7,"unicode":"\u00e9\ud83d\ude00"})";
  r.setting = calib::core::Setting::kLand;
  r.origin = "imported from /mnt/usb/run 1";
  r.promoted_at_ms = 1764118000000;
  r.promoted_by = "qa-lead";
  r.promote_reason = "reviewed, 🙂";
  r.holding_method = Method::kLegacy;
  r.holding_reason = "AINS leaves 0.20 mg (1.8×, limit 1.5×): \"legacy\"\t";
  CalibrationRecord c;
  c.method = Method::kNlsq;
  c.params = params_from(1.2345678901234567e-4);
  c.sigma = calib::core::ParamSet::from_vector(params_from(3e-7).to_vector().cwiseAbs());
  c.params.accel_M(1, 2) = -0.0;
  c.params.gyro_bias_radps(0) = 1.0;  // nlohmann prints an integral double as "1.0"
  c.sigma.table_misalignment_rad(2) = 1e300;
  c.converged = true;
  c.iterations = 3;
  c.runtime_s = 0.1;
  c.warnings = {"first", "second \"quoted\"", ""};
  StoredMetrics m;
  m.orientation_rmse_mdeg = 0.64466574195384;
  m.accel_rmse_ug = std::numeric_limits<double>::quiet_NaN();  // nlohmann: null
  m.heading_offset_gamma_np_rad = -3.0100777e-05;
  m.body_misalignment_theta_bp_rad = {3.5988e-07, -std::numeric_limits<double>::infinity(), 5e-324};
  c.metrics = m;
  row.calibration = c;
  CrosscheckRecord x;
  x.verdict = Verdict::kReview;
  x.k_sigma = 4.0;
  x.failures = {{"accel_bias_mps2[1]", "|Δ| = 12.3 µg > 4σ bound 8.1 µg"}, {"t", "d"}};
  row.crosscheck = x;
  return row;
}

TEST(ExportRowWriter, EveryFieldPresentWithAwkwardStringsAndNumbers) {
  const ExportRow row = full_row();
  EXPECT_EQ(direct(row), reference(row));
}

TEST(ExportRowWriter, EveryOptionalAbsent) {
  ExportRow row;
  row.run.run_id = 1;
  row.run.serial = "S";
  EXPECT_EQ(direct(row), reference(row));
  ExportRow partial = full_row();
  partial.calibration->metrics.reset();
  partial.calibration->warnings.clear();
  partial.crosscheck->failures.clear();
  partial.run.capture_json.clear();
  partial.run.verdict.reset();
  partial.run.crosscheck_verdict.reset();
  partial.run.reasons.clear();
  EXPECT_EQ(direct(partial), reference(partial));
}

TEST(ExportRowWriter, RandomRowsMatchByteForByte) {
  std::mt19937_64 rng(20261126);
  auto finite = [&] {
    for (;;) {
      double v;
      const uint64_t bits = rng();
      std::memcpy(&v, &bits, sizeof v);
      if (std::isfinite(v)) return v;
    }
  };
  auto text = [&] {
    std::string s;
    const int n = static_cast<int>(rng() % 12);
    for (int i = 0; i < n; ++i) s += static_cast<char>(0x20 + rng() % 0x5f);  // printable ASCII
    return s;
  };
  for (int k = 0; k < 500; ++k) {
    ExportRow row = full_row();
    calib::core::ParamVector p, s;
    for (int i = 0; i < calib::core::ParamSet::kSize; ++i) {
      p(i) = finite();
      s(i) = std::abs(finite());
    }
    row.calibration->params = calib::core::ParamSet::from_vector(p);
    row.calibration->sigma = calib::core::ParamSet::from_vector(s);
    row.calibration->runtime_s = finite();
    row.calibration->metrics->heading_offset_gamma_np_rad = finite();
    row.crosscheck->k_sigma = finite();
    row.run.run_id = static_cast<RunId>(rng());
    row.run.serial = text();
    row.run.failure_reason = text();
    row.crosscheck->failures[1].detail = text();
    ASSERT_EQ(direct(row), reference(row)) << "row " << k;
  }
}

TEST(ExportRowWriter, WhatCannotBeWrittenFailsAsBefore) {
  auto message_of = [](const auto& f) -> std::string {
    try {
      f();
    } catch (const std::exception& e) {
      return e.what();
    }
    return "no error";
  };
  ExportRow row = full_row();
  row.calibration->sigma.accel_M(0, 1) = -1e-6;  // a negative σ
  EXPECT_NE(message_of([&] { direct(row); }), "no error");
  EXPECT_EQ(message_of([&] { direct(row); }), message_of([&] { reference(row); }));
  row = full_row();
  row.calibration->params.gyro_M(2, 2) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(message_of([&] { direct(row); }), message_of([&] { reference(row); }));
  row = full_row();
  row.run.diagnosis_json = "[1,2]";  // stored, but not an object
  EXPECT_NE(message_of([&] { direct(row); }).find("diagnosis_json is not a JSON object"),
            std::string::npos);
  EXPECT_EQ(message_of([&] { direct(row); }), message_of([&] { reference(row); }));
  row = full_row();
  row.run.station = "bad \xff utf-8";
  EXPECT_NE(message_of([&] { direct(row); }), "no error");
  EXPECT_EQ(message_of([&] { direct(row); }), message_of([&] { reference(row); }));
}

}  // namespace
}  // namespace imucal::db
