// JSON shapes and text renderings of the read commands (station/control/record_json.hpp), against a
// real SQLite history filled through the repository with seeded values the test recomputes.
#include "station/control/record_json.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <sstream>
#include <string>
#include <vector>

#include "calib/core/param_set.hpp"
#include "db/archive/param_json.hpp"
#include "db/history/sqlite_repository.hpp"
#include "tests/db/history_fixtures.hpp"

namespace imucal::station {
using namespace imucal::station::control;
namespace {

using db::test::TempDir;
using nlohmann::json;

constexpr double kG0 = 9.80665;  // standard gravity, m/s²: 1 µg = 9.80665e-6 m/s²
constexpr double kPi = 3.14159265358979323846;

const std::string kCapture =
    R"({"complete":true,"frames_received":1200,"samples_decoded":600,"samples_lost":3,"samples_filled":3,"imu_resets":0})";

std::vector<std::string> lines_of(const std::string& text) {
  std::vector<std::string> out;
  std::stringstream ss(text);
  for (std::string l; std::getline(ss, l);) out.push_back(l);
  return out;
}

std::string fixed3(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.3f", v);
  return buf;
}

/// SN-A: run 1 (t=10:00, PASS, seed 1), run 2 (t=12:00, REVIEW, seed 2), run 3 (t=11:00, failed),
/// SN-B: run 4 (PASS, seed 4). Start times out of id order so that ordering is by time.
class RecordJson : public ::testing::Test {
 protected:
  void SetUp() override {
    repo_ = std::make_unique<db::history::SqliteRepository>(dir_.file("history.sqlite"));
    t10_ = db::history::parse_time_utc("2024-05-01T10:00:00Z");
    t11_ = db::history::parse_time_utc("2024-05-01T11:00:00Z");
    t12_ = db::history::parse_time_utc("2024-05-01T12:00:00Z");
    r1_ = repo_->create_run(db::test::new_run("SN-A", t10_));
    db::history::RunCompletion c1 = db::test::pass_completion(1, t10_ + 754000);  // 12 min 34 s
    c1.capture_json = kCapture;
    repo_->finish_run(r1_, c1);
    r2_ = repo_->create_run(db::test::new_run("SN-A", t12_));
    repo_->finish_run(r2_, db::test::review_completion(2, t12_ + 60000));
    r3_ = repo_->create_run(db::test::new_run("SN-A", t11_));
    db::history::RunCompletion c3;
    c3.state = db::history::RunState::kFailed;
    c3.ended_at_ms = t11_ + 5000;
    c3.reason = "capture: IMU reset at sample 412";
    repo_->finish_run(r3_, c3);
    r4_ = repo_->create_run(db::test::new_run("SN-B", t10_ + 1));
    repo_->finish_run(r4_, db::test::pass_completion(4, t10_ + 100000));
  }

  TempDir dir_;
  std::unique_ptr<db::history::SqliteRepository> repo_;
  db::history::TimestampMs t10_ = 0, t11_ = 0, t12_ = 0;
  db::history::RunId r1_ = 0, r2_ = 0, r3_ = 0, r4_ = 0;
};

Request read(const std::string& cmd, const json& args) {
  return validate_request(json{{"id", 1}, {"cmd", cmd}, {"args", args}});
}

TEST_F(RecordJson, HistoryIsNewestFirstWithCaptureAndReasons) {
  const json h = answer_repository_read(*repo_, read("history", {{"serial", "SN-A"}}));
  EXPECT_EQ(h.at("serial"), "SN-A");
  const json& runs = h.at("runs");
  ASSERT_EQ(runs.size(), 3u);
  EXPECT_EQ(runs[0].at("run_id"), r2_);  // 12:00
  EXPECT_EQ(runs[1].at("run_id"), r3_);  // 11:00
  EXPECT_EQ(runs[2].at("run_id"), r1_);  // 10:00
  EXPECT_EQ(runs[0].at("verdict"), "REVIEW");
  EXPECT_EQ(runs[1].at("state"), "failed");
  EXPECT_EQ(runs[1].at("failure_reason"), "capture: IMU reset at sample 412");
  EXPECT_TRUE(runs[0].at("capture").is_null());
  EXPECT_EQ(runs[2].at("capture"), json::parse(kCapture));

  const json limited =
      answer_repository_read(*repo_, read("history", {{"serial", "SN-A"}, {"limit", 1}}));
  ASSERT_EQ(limited.at("runs").size(), 1u);
  EXPECT_EQ(limited["runs"][0].at("run_id"), r2_);

  // Text: a header line, then one line per run in the same order, each starting with its id.
  const auto lines = lines_of(render_history_text(h));
  ASSERT_GE(lines.size(), 5u);
  EXPECT_NE(lines[0].find("SN-A"), std::string::npos);
  EXPECT_EQ(lines[1].rfind("RUN", 0), 0u);
  EXPECT_EQ(lines[2].rfind(std::to_string(r2_) + " ", 0), 0u) << lines[2];
  EXPECT_EQ(lines[3].rfind(std::to_string(r3_) + " ", 0), 0u) << lines[3];
  EXPECT_EQ(lines[4].rfind(std::to_string(r1_) + " ", 0), 0u) << lines[4];
  EXPECT_NE(lines[2].find("REVIEW"), std::string::npos);
  EXPECT_NE(lines[3].find("capture: IMU reset at sample 412"), std::string::npos);
  EXPECT_NE(lines[4].find("2024-05-01 10:00:00"), std::string::npos);
  EXPECT_NE(lines[4].find("12 min 34 s"), std::string::npos) << lines[4];
}

// Issue #19 item 2: a run whose cross-check passed but which the gap check and a partial archive
// sent to review showed "PASS" in history, show, export and the run's end line.
TEST_F(RecordJson, EveryViewShowsTheRunVerdictWithItsReasonsAndTheCrossCheckLabelled) {
  const db::history::RunId id = repo_->create_run(db::test::new_run("SN-C", t10_));
  db::history::RunCompletion c = db::test::pass_completion(5, t10_ + 60000);
  c.state = db::history::RunState::kReview;
  c.reasons = {{"partial archive", "partial archive: aborted at step 9 of 18 — REVIEW at best"},
               {"gap", "sim-to-real gap: explained by gyro_g_sensitivity"}};
  repo_->finish_run(id, c);

  const json h = answer_repository_read(*repo_, read("history", {{"serial", "SN-C"}}));
  const json& run = h.at("runs").at(0);
  EXPECT_EQ(run.at("verdict"), "REVIEW");
  EXPECT_EQ(run.at("crosscheck_verdict"), "PASS");
  ASSERT_EQ(run.at("reasons").size(), 2u);
  EXPECT_EQ(run["reasons"][1].at("source"), "gap");
  const auto lines = lines_of(render_history_text(h));
  ASSERT_GE(lines.size(), 3u);
  const std::size_t verdict_col = lines[1].find("VERDICT"),
                    xcheck_col = lines[1].find("CROSS-CHECK");
  ASSERT_NE(verdict_col, std::string::npos);
  ASSERT_NE(xcheck_col, std::string::npos);
  EXPECT_EQ(lines[2].substr(verdict_col, 6), "REVIEW") << lines[2];
  EXPECT_EQ(lines[2].substr(xcheck_col, 4), "PASS") << lines[2];

  const json s = answer_repository_read(*repo_, read("show", {{"run_id", id}}));
  const std::string text = render_show_text(s);
  EXPECT_EQ(
      text.rfind(
          "Run " + std::to_string(id) + "  SN-C  review  verdict REVIEW  (cross-check PASS)\n", 0),
      0u)
      << text;
  EXPECT_NE(text.find("2 reasons:\n    [partial archive] partial archive: aborted at step 9"),
            std::string::npos)
      << text;
  EXPECT_NE(text.find("    [gap] sim-to-real gap: explained by gyro_g_sensitivity"),
            std::string::npos);
  EXPECT_NE(text.find("Cross-check PASS"), std::string::npos) << "labelled as the cross-check's";

  const std::string line = outcome_line(s.at("run"));
  EXPECT_EQ(line.rfind("run " + std::to_string(id) +
                           " SN-C: review, verdict REVIEW (cross-check PASS) — partial archive",
                       0),
            0u)
      << line;

  const json e =
      answer_repository_read(*repo_, read("export", {{"serial", "SN-C"}, {"format", "json"}}));
  for (const json& row : json::parse(e.at("content").get<std::string>()))
    EXPECT_EQ(row.at("verdict"), "REVIEW");
  EXPECT_THROW(repo_->active_params("SN-C"), db::history::NotFound) << "REVIEW is never active";
}

// Issue #19 item 4: a land run's show said "AINS and NLSQ agree on every parameter" (the second
// method was legacy, three terms were not compared), printed the table misalignment it cannot see
// as "0.000 ± 0.000", left out the housing-orientation note and ran "legacyconverged" together.
TEST_F(RecordJson, AFieldRunShowsItsMethodsWhatWasNotComparedAndWhatIsNotObservable) {
  db::history::NewRun nr = db::test::new_run("SN-L", t10_);
  nr.setting = calib::core::Setting::kLand;
  nr.origin = "imported from /media/land-01";
  const db::history::RunId id = repo_->create_run(nr);
  db::history::RunCompletion c = db::test::pass_completion(6, t10_ + 60000);
  c.calibrations = {db::test::seeded_calibration(6, db::history::Method::kAins, false),
                    db::test::seeded_calibration(6, db::history::Method::kLegacy, false)};
  const std::vector<std::string> table = {"table_misalignment_rad[0]", "table_misalignment_rad[1]",
                                          "table_misalignment_rad[2]"};
  for (auto& cal : c.calibrations) {
    cal.body_frame = calib::core::BodyFrame::kAccelSymmetric;
    cal.params.table_misalignment_rad.setZero();
    cal.sigma.table_misalignment_rad.setZero();
    cal.unobservable = table;
    cal.notes = {"housing orientation: not observable on land (no attitude reference)"};
  }
  c.crosscheck->not_compared = table;
  repo_->finish_run(id, c);
  repo_->promote(id, "qa", "field recalibration", t10_ + 120000);

  const json s = answer_repository_read(*repo_, read("show", {{"run_id", id}}));
  const std::string text = render_show_text(s);
  EXPECT_NE(text.find("Cross-check PASS (AINS against legacy, bound 4σ): they agree on every "
                      "compared parameter; 3 not compared (not observable by both: "
                      "table_misalignment_rad[0]"),
            std::string::npos)
      << text;
  EXPECT_EQ(text.find("NLSQ"), std::string::npos) << text;
  for (const auto& line : lines_of(text))
    if (line.find("table_misalignment_rad[") == 2) {
      EXPECT_NE(line.find("not observable"), std::string::npos) << line;
      EXPECT_EQ(line.find("0.000 ± 0.000"), std::string::npos) << line;
    }
  EXPECT_NE(text.find("not observable: housing orientation"), std::string::npos) << text;
  EXPECT_NE(text.find("accelerometer triad's own orthogonal frame"), std::string::npos) << text;
  EXPECT_EQ(text.find("legacyconverged"), std::string::npos) << text;
  EXPECT_NE(text.find("legacy  converged"), std::string::npos) << text;
  // params says which terms its set does not determine (their σ 0 means "not estimated").
  const json p = answer_repository_read(*repo_, read("params", {{"serial", "SN-L"}}));
  EXPECT_EQ(p.at("source").at("not_observable"), json(table));
  EXPECT_EQ(p.at("source").at("body_frame"), "accel_symmetric");
}

// Issue #19 item 11: show printed "Gap diagnosis: consistent  (consistent)".
TEST_F(RecordJson, ShowSaysAConsistentGapOnce) {
  repo_->set_diagnosis(r1_, R"({"verdict":"consistent","summary":"the run is consistent"})");
  const std::string text =
      render_show_text(answer_repository_read(*repo_, read("show", {{"run_id", r1_}})));
  const std::size_t at = text.find("Gap diagnosis: consistent");
  ASSERT_NE(at, std::string::npos) << text;
  const std::string line = text.substr(at, text.find('\n', at) - at);
  EXPECT_EQ(line, "Gap diagnosis: consistent") << text;
}

TEST_F(RecordJson, ShowCarriesBothParameterSetsBitExact) {
  const json s = answer_repository_read(*repo_, read("show", {{"run_id", r1_}}));
  EXPECT_EQ(s.at("run").at("run_id"), r1_);
  EXPECT_EQ(s.at("run").at("capture").at("samples_lost"), 3);
  ASSERT_EQ(s.at("calibrations").size(), 2u);
  for (int mi = 0; mi < 2; ++mi) {
    const json& c = s["calibrations"][static_cast<std::size_t>(mi)];
    EXPECT_EQ(c.at("method"), mi == 0 ? "ains" : "nlsq");
    calib::core::ParamSet sigma;
    const calib::core::ParamSet p =
        db::archive::param_set_from_json(c.at("params"), "show", &sigma);
    const calib::core::ParamVector want = db::test::seeded_params(1, mi).to_vector();
    const calib::core::ParamVector want_sigma = db::test::seeded_sigma(1, mi).to_vector();
    for (int i = 0; i < calib::core::ParamSet::kSize; ++i) {
      EXPECT_EQ(p.to_vector()(i), want(i)) << i;
      EXPECT_EQ(sigma.to_vector()(i), want_sigma(i)) << i;
    }
    EXPECT_TRUE(c.at("metrics").is_object());
  }
  EXPECT_EQ(s.at("crosscheck").at("verdict"), "PASS");
}

TEST_F(RecordJson, ShowTextUsesHumanUnits) {
  const json s = answer_repository_read(*repo_, read("show", {{"run_id", r2_}}));
  const std::string text = render_show_text(s);
  const calib::core::ParamVector ains = db::test::seeded_params(2, 0).to_vector();
  const calib::core::ParamVector nlsq = db::test::seeded_params(2, 1).to_vector();
  // Converted here from first principles, not with the code's factors.
  const std::string accel_bias_ug = fixed3(ains(1) / (1e-6 * kG0));
  const std::string nlsq_accel_bias_ug = fixed3(nlsq(1) / (1e-6 * kG0));
  const std::string gyro_bias_dph = fixed3(ains(12) * 180.0 / kPi * 3600.0);
  const std::string scale_ppm = fixed3(ains(3) * 1e6);  // accel_M[0][0]
  const std::string table_arcsec = fixed3(ains(26) * 180.0 / kPi * 3600.0);
  bool found_accel = false, found_gyro = false, found_scale = false, found_table = false;
  for (const auto& l : lines_of(text)) {
    if (l.rfind("  accel_bias_mps2[1] ", 0) == 0) {  // the table row
      found_accel = true;
      EXPECT_NE(l.find("µg"), std::string::npos) << l;
      EXPECT_NE(l.find(accel_bias_ug), std::string::npos) << l << " wants " << accel_bias_ug;
      EXPECT_NE(l.find(nlsq_accel_bias_ug), std::string::npos) << l;
    }
    if (l.rfind("  gyro_bias_radps[0] ", 0) == 0) {  // the table row
      found_gyro = true;
      EXPECT_NE(l.find("deg/h"), std::string::npos) << l;
      EXPECT_NE(l.find(gyro_bias_dph), std::string::npos) << l << " wants " << gyro_bias_dph;
    }
    if (l.rfind("  accel_M[0][0] ", 0) == 0) {  // the table row
      found_scale = true;
      EXPECT_NE(l.find("ppm"), std::string::npos) << l;
      EXPECT_NE(l.find(scale_ppm), std::string::npos) << l;
    }
    if (l.rfind("  table_misalignment_rad[2] ", 0) == 0) {  // the table row
      found_table = true;
      EXPECT_NE(l.find("arcsec"), std::string::npos) << l;
      EXPECT_NE(l.find(table_arcsec), std::string::npos) << l;
    }
  }
  EXPECT_TRUE(found_accel && found_gyro && found_scale && found_table) << text;
  EXPECT_NE(text.find("Cross-check REVIEW"), std::string::npos) << text;
  EXPECT_NE(text.find("|Δ| = 12.3 µg > 4σ bound 8.1 µg"), std::string::npos) << text;

  // A failed run without results says so and shows its reason.
  const std::string failed =
      render_show_text(answer_repository_read(*repo_, read("show", {{"run_id", r3_}})));
  EXPECT_NE(failed.find("No calibration results."), std::string::npos) << failed;
  EXPECT_NE(failed.find("capture: IMU reset at sample 412"), std::string::npos) << failed;
  // Capture counters of run 1 are shown.
  const std::string first =
      render_show_text(answer_repository_read(*repo_, read("show", {{"run_id", r1_}})));
  EXPECT_NE(first.find("Capture (complete)"), std::string::npos) << first;
  EXPECT_NE(first.find("samples_lost"), std::string::npos) << first;
}

TEST_F(RecordJson, ParamsIsTheActiveSetLoadableByReadParamFile) {
  // Run 2 (REVIEW, later) must not replace run 1's PASS set.
  const json p = answer_repository_read(*repo_, read("params", {{"serial", "SN-A"}}));
  const std::string path = dir_.file("active.json");
  {
    FILE* f = std::fopen(path.c_str(), "w");
    ASSERT_NE(f, nullptr);
    const std::string text = render_params_text(p);
    std::fwrite(text.data(), 1, text.size(), f);
    std::fclose(f);
  }
  calib::core::ParamSet sigma;
  const calib::core::ParamSet loaded = db::archive::read_param_file(path, &sigma);
  EXPECT_EQ(loaded.to_vector(), db::test::seeded_params(1, 0).to_vector());
  EXPECT_EQ(sigma.to_vector(), db::test::seeded_sigma(1, 0).to_vector());
  // The schema's keys, sigma and "source": the run the set comes from (issue #19 item 3), which
  // `stationctl params --bare` leaves out for a loader that accepts nothing else.
  const json& source = p.at("source");
  EXPECT_EQ(source.at("run_id"), r1_);
  EXPECT_EQ(source.at("serial"), "SN-A");
  EXPECT_EQ(source.at("method"), "ains");
  EXPECT_EQ(source.at("verdict"), "PASS");
  EXPECT_EQ(source.at("started_at"), "2024-05-01T10:00:00.000Z");
  for (auto it = p.begin(); it != p.end(); ++it) {
    bool known = it.key() == "sigma" || it.key() == "source";
    for (const char* k : db::archive::kParamSetKeys) known = known || it.key() == k;
    EXPECT_TRUE(known) << it.key();
  }
}

TEST_F(RecordJson, ExportContentMatchesTheRuns) {
  // SN-A: runs 1 and 2 have two calibrations each, run 3 none -> 5 rows.
  const json csv =
      answer_repository_read(*repo_, read("export", {{"serial", "SN-A"}, {"format", "csv"}}));
  EXPECT_EQ(csv.at("format"), "csv");
  EXPECT_EQ(csv.at("rows"), 5);
  const auto lines = lines_of(csv.at("content").get<std::string>());
  EXPECT_EQ(lines.size(), 6u);  // header + 5
  EXPECT_EQ(lines[0].rfind("run_id,serial,", 0), 0u);

  const json all = answer_repository_read(*repo_, read("export", {{"format", "json"}}));
  const json arr = json::parse(all.at("content").get<std::string>());
  ASSERT_TRUE(arr.is_array());
  EXPECT_EQ(arr.size(), 7u);  // + SN-B's two
  // since 11:00 leaves run 3 (11:00) and run 2 (12:00): 1 + 2 rows.
  const json since = answer_repository_read(
      *repo_, read("export", {{"format", "json"}, {"since", "2024-05-01T11:00:00Z"}}));
  EXPECT_EQ(since.at("rows"), 3);
}

TEST_F(RecordJson, RepositoryErrorsKeepTheirKind) {
  auto kind_of = [&](const Request& r) {
    try {
      (void)answer_repository_read(*repo_, r);
    } catch (const db::history::DbError& e) {
      return std::string(db::history::to_string(e.kind()));
    }
    return std::string("no error");
  };
  const std::string not_found = db::history::to_string(db::history::DbErrorKind::kNotFound);
  const std::string invalid = db::history::to_string(db::history::DbErrorKind::kInvalidInput);
  EXPECT_EQ(kind_of(read("history", {{"serial", "SN-Z"}})), not_found);
  EXPECT_EQ(kind_of(read("history", {{"serial", "bad serial"}})), invalid);
  EXPECT_EQ(kind_of(read("show", {{"run_id", 999}})), not_found);
  EXPECT_EQ(kind_of(read("params", {{"serial", "SN-Z"}})), not_found);
  // An export of an unknown unit is an error, not a silently empty file.
  EXPECT_EQ(kind_of(read("export", {{"serial", "SN-Z"}, {"format", "csv"}})), not_found);
  EXPECT_THROW((void)answer_repository_read(*repo_, read("ping", json::object())),
               std::invalid_argument);
}

TEST(RecordJsonText, DurationsProgressAndStatus) {
  EXPECT_EQ(format_duration_s(0.4), "0 s");
  EXPECT_EQ(format_duration_s(59.4), "59 s");
  EXPECT_EQ(format_duration_s(185), "3 min 05 s");
  EXPECT_EQ(format_duration_s(3600 + 120 + 59), "1 h 02 min");
  EXPECT_EQ(format_duration_s(-1), "?");

  const json live = json::parse(R"({"run_id":7,"serial":"SIM-0001","sequence":"short",
      "operator":"op","state":"running","phase":"resting","step":3,"steps":18,
      "time_left_s":12.4,"verdict":null,"reason":"","started_at":"2024-05-01T10:00:00.000Z",
      "capture":{"samples_decoded":100,"samples_lost":2}})");
  EXPECT_EQ(progress_line(live), "run 7 SIM-0001: step 3/18 resting, 12 s left");
  json calibrating = live;
  calibrating["state"] = "calibrating";
  calibrating["phase"] = "calibrating";
  EXPECT_EQ(progress_line(calibrating), "run 7 SIM-0001: calibrating");
  json done = live;
  done["state"] = "review";
  done["verdict"] = "REVIEW";
  done["reason"] = "gyro_M[0][0] disagrees";
  EXPECT_EQ(outcome_line(done), "run 7 SIM-0001: review, verdict REVIEW — gyro_M[0][0] disagrees");

  const json status = {
      {"daemon",
       {{"version", "0.1.0"}, {"pid", 42}, {"station", "sim-station"}, {"uptime_s", 3725.0}}},
      {"state", "busy"},
      {"run", live},
      {"last_run", nullptr}};
  const std::string text = render_status_text(status);
  EXPECT_NE(text.find("stationd 0.1.0 (pid 42) at station sim-station, up 1 h 02 min: busy"),
            std::string::npos)
      << text;
  EXPECT_NE(text.find("Active run 7 SIM-0001: step 3/18 resting, 12 s left"), std::string::npos)
      << text;
  EXPECT_NE(text.find("samples_lost 2"), std::string::npos) << text;
  json idle = status;
  idle["state"] = "idle";
  idle["run"] = nullptr;
  idle["last_run"] = done;
  const std::string idle_text = render_status_text(idle);
  EXPECT_NE(idle_text.find("No active run."), std::string::npos) << idle_text;
  EXPECT_NE(idle_text.find("Last run 7 SIM-0001: review"), std::string::npos) << idle_text;
}

}  // namespace
}  // namespace imucal::station
