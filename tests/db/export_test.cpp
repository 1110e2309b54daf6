// Export (stationctl export --serial/--since --format csv|json): the CSV is RFC 4180 and parses
// back (with an independent little reader below) to exactly the stored values; the JSON parses
// with nlohmann and its parameter sets load with the strict parameter-set reader; filters select
// the right rows; a failing stream is an error, not a silent truncation.
#include "db/history/export.hpp"

#include <gtest/gtest.h>

#include <cstdlib>
#include <map>
#include <set>
#include <sstream>

#include "db/archive/param_json.hpp"
#include "db/archive/run_archive.hpp"
#include "db/history/sqlite_repository.hpp"
#include "tests/db/history_fixtures.hpp"

namespace imucal::db {
using namespace imucal::db::history;
namespace {

using nlohmann::json;
using test::TempDir;

constexpr TimestampMs kT0Export = 1714560000000;  // 2024-05-01T10:40:00Z
constexpr TimestampMs kDay = 86400000;

/// Minimal RFC 4180 reader written for this test: records end in CRLF, quoted fields may hold
/// commas, CR/LF and doubled quotes. Fails the test on anything else.
std::vector<std::vector<std::string>> parse_csv(const std::string& text) {
  std::vector<std::vector<std::string>> rows;
  std::vector<std::string> row;
  std::string field;
  std::size_t i = 0;
  bool quoted = false, field_started = false;
  while (i < text.size()) {
    const char c = text[i];
    if (quoted) {
      if (c == '"') {
        if (i + 1 < text.size() && text[i + 1] == '"') {
          field += '"';
          i += 2;
          continue;
        }
        quoted = false;
        ++i;
        continue;
      }
      field += c;
      ++i;
      continue;
    }
    if (c == '"' && !field_started) {
      quoted = true;
      field_started = true;
      ++i;
    } else if (c == ',') {
      row.push_back(field);
      field.clear();
      field_started = false;
      ++i;
    } else if (c == '\r') {
      if (i + 1 >= text.size() || text[i + 1] != '\n') {
        ADD_FAILURE() << "bare CR at byte " << i;
        return rows;
      }
      row.push_back(field);
      rows.push_back(row);
      row.clear();
      field.clear();
      field_started = false;
      i += 2;
    } else if (c == '\n' || c == '"') {
      ADD_FAILURE() << "unexpected " << (c == '\n' ? "bare LF" : "quote") << " at byte " << i;
      return rows;
    } else {
      field += c;
      field_started = true;
      ++i;
    }
  }
  EXPECT_TRUE(row.empty() && field.empty() && !quoted) << "last record not terminated by CRLF";
  return rows;
}

double to_double(const std::string& s) {
  char* end = nullptr;
  const double v = std::strtod(s.c_str(), &end);
  EXPECT_TRUE(!s.empty() && *end == '\0') << "not a number: \"" << s << "\"";
  return v;
}

struct Stored {
  RunId id;
  std::string serial;
  TimestampMs t;
  long seed;  // 0: no calibrations
  RunState state;
};

/// Two serials over four days; PASS, REVIEW and failed (no calibrations) runs; a failure reason
/// with a comma, quotes and a newline to exercise the quoting.
class ExportTest : public ::testing::Test {
 protected:
  void SetUp() override {
    repo_ = std::make_unique<SqliteRepository>(dir_.file("export.db"));
    add("SIM-A", kT0Export, 1, RunState::kDone);
    add("SIM-B", kT0Export + kDay, 2, RunState::kReview);
    add("SIM-A", kT0Export + 2 * kDay, 0, RunState::kFailed);
    add("SIM-B", kT0Export + 2 * kDay, 3,
        RunState::kDone);  // same time as the failed run: id order
    add("SIM-A", kT0Export + 3 * kDay, 4, RunState::kDone);
  }

  void add(const std::string& serial, TimestampMs t, long seed, RunState state) {
    const RunId id = repo_->create_run(test::new_run(serial, t));
    if (state == RunState::kDone) {
      repo_->finish_run(id, test::pass_completion(seed, t + 1000));
    } else if (state == RunState::kReview) {
      RunCompletion c = test::review_completion(seed, t + 1000);
      c.capture_json = kCaptureJson;
      repo_->finish_run(id, c);
    } else {
      repo_->update_run_state(id, state, kReason);
    }
    stored_.push_back({id, serial, t, seed, state});
  }

  /// Expected (run id, method) rows in export order for a filter.
  std::vector<std::pair<RunId, std::string>> expected_rows(const ExportFilter& f) const {
    std::vector<Stored> runs;
    for (const auto& s : stored_)
      if ((!f.serial || s.serial == *f.serial) && (!f.since_ms || s.t >= *f.since_ms))
        runs.push_back(s);
    std::sort(runs.begin(), runs.end(), [](const Stored& a, const Stored& b) {
      return a.t != b.t ? a.t < b.t : a.id < b.id;
    });
    std::vector<std::pair<RunId, std::string>> rows;
    for (const auto& r : runs) {
      if (r.seed == 0) {
        rows.push_back({r.id, ""});
      } else {
        rows.push_back({r.id, "ains"});
        rows.push_back({r.id, "nlsq"});
      }
    }
    return rows;
  }

  const Stored& stored(RunId id) const {
    for (const auto& s : stored_)
      if (s.id == id) return s;
    throw std::runtime_error("unknown id");
  }

  static constexpr const char* kCaptureJson =
      R"({"frames_received": 40012, "frames_logged": 40012, "samples_decoded": 10001, "samples_lost": 2})";
  static constexpr const char* kReason = "table fault 17, \"axis 2\" overcurrent\nstep 3/12";
  TempDir dir_;
  std::unique_ptr<SqliteRepository> repo_;
  std::vector<Stored> stored_;
};

TEST_F(ExportTest, CsvParsesBackToTheStoredValuesForEveryFilter) {
  const std::vector<ExportFilter> filters = {
      {},
      {std::string("SIM-A"), std::nullopt, std::nullopt},
      {std::nullopt, kT0Export + 2 * kDay, std::nullopt},
      {std::string("SIM-B"), kT0Export + kDay + 1, std::nullopt},
      {std::string("SIM-A"), kT0Export + 10 * kDay, std::nullopt}};
  for (const ExportFilter& f : filters) {
    std::ostringstream os;
    const std::size_t n = export_csv(*repo_, f, os);
    const auto rows = parse_csv(os.str());
    ASSERT_FALSE(rows.empty());
    const auto& header = rows[0];
    ASSERT_EQ(header.size(), 24u + 11u + 2u * calib::core::ParamSet::kSize + 2u +
                                 db::archive::CaptureInfo::counters().size() + 11u);
    std::map<std::string, std::size_t> col;
    for (std::size_t c = 0; c < header.size(); ++c) col[header[c]] = c;
    ASSERT_EQ(col.size(), header.size()) << "duplicate column names";
    for (const char* name : {"run_id",
                             "serial",
                             "state",
                             "verdict",
                             "crosscheck_verdict",
                             "started_at",
                             "method",
                             "failure_reason",
                             "setting",
                             "origin",
                             "promoted_at",
                             "promoted_by",
                             "promote_reason",
                             "accel_M[1][2]",
                             "sigma.gyro_bias_radps[0]",
                             "crosscheck_k_sigma",
                             "crosscheck_failures",
                             "capture.frames_received",
                             "capture.samples_lost",
                             "capture.rest_samples"})
      ASSERT_TRUE(col.count(name)) << name;

    const auto expected = expected_rows(f);
    ASSERT_EQ(n, expected.size());
    ASSERT_EQ(rows.size(), expected.size() + 1);
    for (std::size_t r = 0; r < expected.size(); ++r) {
      const auto& row = rows[r + 1];
      ASSERT_EQ(row.size(), header.size()) << "row " << r;
      const RunId id = std::stoll(row[col["run_id"]]);
      EXPECT_EQ(id, expected[r].first) << "row " << r;
      EXPECT_EQ(row[col["method"]], expected[r].second) << "row " << r;
      const Stored& s = stored(id);
      EXPECT_EQ(row[col["serial"]], s.serial);
      EXPECT_EQ(row[col["state"]], to_string(s.state));
      EXPECT_EQ(row[col["verdict"]], to_string(*run_verdict(s.state))) << "the run's verdict";
      EXPECT_EQ(row[col["outcome_of"]], "unit") << "done, review, failed: the unit's own (#50)";
      EXPECT_EQ(row[col["setting"]], "factory");
      EXPECT_EQ(row[col["promoted_at"]], "");
      EXPECT_EQ(parse_time_utc(row[col["started_at"]]), s.t);
      if (s.seed == 0) {
        EXPECT_EQ(row[col["crosscheck_verdict"]], "");
        EXPECT_EQ(row[col["failure_reason"]], kReason) << "quoted field round trip";
        EXPECT_EQ(row[col["accel_M[1][2]"]], "");
        EXPECT_EQ(row[col["crosscheck_k_sigma"]], "");
        EXPECT_EQ(row[col["capture.frames_received"]], "");
        continue;
      }
      EXPECT_EQ(row[col["crosscheck_verdict"]], s.state == RunState::kDone ? "PASS" : "REVIEW");
      EXPECT_EQ(to_double(row[col["crosscheck_k_sigma"]]), 4.0);
      if (s.state == RunState::kReview) {
        // The failing term with its detail (the review fixture's one failure), and the counters.
        EXPECT_EQ(row[col["crosscheck_failures"]],
                  "accel_bias_mps2[1]: accel_bias_mps2[1]: |Δ| = 12.3 µg > 4σ bound 8.1 µg");
        EXPECT_EQ(row[col["capture.frames_received"]], "40012");
        EXPECT_EQ(row[col["capture.samples_lost"]], "2");
        EXPECT_EQ(row[col["capture.rest_samples"]], "") << "a counter the run did not store";
      } else {
        EXPECT_EQ(row[col["crosscheck_failures"]], "");
        EXPECT_EQ(row[col["capture.frames_received"]], "");
      }
      EXPECT_EQ(parse_time_utc(row[col["ended_at"]]), s.t + 1000);
      const int mi = row[col["method"]] == "ains" ? 0 : 1;
      const calib::core::ParamVector p = test::seeded_params(s.seed, mi).to_vector();
      const calib::core::ParamVector sg = test::seeded_sigma(s.seed, mi).to_vector();
      for (int i = 0; i < calib::core::ParamSet::kSize; ++i) {
        const std::string& name = calib::core::param_info(i).name;
        EXPECT_EQ(to_double(row[col[name]]), p(i)) << name << " bit-exact";
        EXPECT_EQ(to_double(row[col["sigma." + name]]), sg(i)) << name;
      }
      const CalibrationRecord c =
          test::seeded_calibration(s.seed, mi == 0 ? Method::kAins : Method::kNlsq);
      EXPECT_EQ(to_double(row[col["runtime_s"]]), c.runtime_s);
      EXPECT_EQ(to_double(row[col["accel_rmse_ug"]]), c.metrics->accel_rmse_ug);
      EXPECT_EQ(std::stoi(row[col["iterations"]]), c.iterations);
    }
  }
}

TEST_F(ExportTest, JsonParsesBackWithStrictParameterSetsForEveryFilter) {
  const std::vector<ExportFilter> filters = {
      {},
      {std::string("SIM-B"), std::nullopt, std::nullopt},
      {std::nullopt, kT0Export + 3 * kDay, std::nullopt},
      {std::string("SIM-B"), kT0Export + 100 * kDay, std::nullopt}};
  for (const ExportFilter& f : filters) {
    std::ostringstream os;
    const std::size_t n = export_json(*repo_, f, os);
    const json j = json::parse(os.str());
    ASSERT_TRUE(j.is_array());
    const auto expected = expected_rows(f);
    ASSERT_EQ(j.size(), expected.size());
    ASSERT_EQ(n, expected.size());
    for (std::size_t r = 0; r < expected.size(); ++r) {
      const json& o = j[r];
      EXPECT_EQ(o.at("run_id").get<RunId>(), expected[r].first);
      const Stored& s = stored(expected[r].first);
      EXPECT_EQ(o.at("serial"), s.serial);
      EXPECT_EQ(o.at("started_at_ms").get<TimestampMs>(), s.t);
      EXPECT_EQ(parse_time_utc(o.at("started_at").get<std::string>()), s.t);
      if (expected[r].second.empty()) {
        EXPECT_TRUE(o.at("calibration").is_null());
        EXPECT_TRUE(o.at("crosscheck").is_null());
        EXPECT_EQ(o.at("verdict"), to_string(*run_verdict(s.state)));
        EXPECT_TRUE(o.at("crosscheck_verdict").is_null());
        EXPECT_EQ(o.at("failure_reason"), kReason);
        continue;
      }
      EXPECT_EQ(o.at("crosscheck").at("verdict"), s.state == RunState::kDone ? "PASS" : "REVIEW");
      EXPECT_EQ(o.at("crosscheck_verdict"), o.at("crosscheck").at("verdict"));
      EXPECT_EQ(o.at("verdict"), to_string(*run_verdict(s.state)));
      EXPECT_EQ(o.at("crosscheck").at("failures").size(), s.state == RunState::kDone ? 0u : 1u);
      if (s.state == RunState::kReview) {
        EXPECT_EQ(o.at("capture").at("samples_decoded"), 10001);
      }
      const json& c = o.at("calibration");
      EXPECT_EQ(c.at("method"), expected[r].second);
      const int mi = expected[r].second == "ains" ? 0 : 1;
      calib::core::ParamSet sigma;
      const calib::core::ParamSet p =
          db::archive::param_set_from_json(c.at("params"), "export", &sigma);
      EXPECT_EQ(p.to_vector(), test::seeded_params(s.seed, mi).to_vector());
      EXPECT_EQ(sigma.to_vector(), test::seeded_sigma(s.seed, mi).to_vector());
      EXPECT_EQ(
          c.at("metrics").at("orientation_rmse_mdeg").get<double>(),
          test::seeded_calibration(s.seed, Method::kAins).metrics->orientation_rmse_mdeg + mi);
    }
  }
}

// NDJSON is the JSON export's objects, one per line, in the same order; export_history picks the
// format by name and refuses an unknown one.
TEST_F(ExportTest, NdjsonIsTheJsonExportOneObjectPerLine) {
  for (const ExportFilter& f :
       std::vector<ExportFilter>{{}, {std::string("SIM-B"), std::nullopt, std::nullopt}}) {
    std::ostringstream js, nd;
    const std::size_t n = export_json(*repo_, f, js);
    ASSERT_EQ(export_ndjson(*repo_, f, nd), n);
    const json array = json::parse(js.str());
    std::istringstream lines(nd.str());
    std::size_t k = 0;
    for (std::string line; std::getline(lines, line); ++k) {
      ASSERT_LT(k, array.size());
      EXPECT_EQ(json::parse(line), array[k]) << k;
    }
    EXPECT_EQ(k, n);
    std::ostringstream by_name;
    EXPECT_EQ(export_history(*repo_, f, "ndjson", by_name), n);
    EXPECT_EQ(by_name.str(), nd.str());
  }
  std::ostringstream os;
  EXPECT_THROW(export_history(*repo_, {}, "xml", os), InvalidInput);
}

TEST_F(ExportTest, EmptyResultIsAHeaderOrAnEmptyArray) {
  ExportFilter none{std::string("SIM-A"), kT0Export + 365 * kDay, std::nullopt};
  std::ostringstream csv, js;
  EXPECT_EQ(export_csv(*repo_, none, csv), 0u);
  EXPECT_EQ(parse_csv(csv.str()).size(), 1u);
  EXPECT_EQ(export_json(*repo_, none, js), 0u);
  EXPECT_EQ(json::parse(js.str()), json::array());
  // An unknown (but valid) serial exports nothing; an invalid one is refused.
  EXPECT_EQ(export_csv(*repo_, {std::string("SIM-ZZZ"), std::nullopt, std::nullopt}, csv), 0u);
  EXPECT_THROW(export_csv(*repo_, {std::string("SIM A"), std::nullopt, std::nullopt}, csv),
               InvalidInput);
}

TEST_F(ExportTest, AFailingStreamIsAnIoError) {
  std::ostringstream os;
  os.setstate(std::ios::badbit);
  EXPECT_THROW(export_csv(*repo_, {}, os), IoError);
  EXPECT_THROW(export_json(*repo_, {}, os), IoError);
  EXPECT_THROW(export_ndjson(*repo_, {}, os), IoError);
}

TEST_F(ExportTest, ActiveParamsJsonLoadsWithTheStrictParameterSetReader) {
  const ActiveCalibration a = repo_->active_params("SIM-A");
  const json j = active_params_json(a);
  calib::core::ParamSet sigma;
  const calib::core::ParamSet p = db::archive::param_set_from_json(j, "params SIM-A", &sigma);
  EXPECT_EQ(p.to_vector(), test::seeded_params(4, 0).to_vector()) << "latest PASS is seed 4, AINS";
  EXPECT_EQ(sigma.to_vector(), test::seeded_sigma(4, 0).to_vector());

  const json d = run_details_json(repo_->show(stored_[1].id));
  EXPECT_EQ(d.at("run").at("state"), "review");
  EXPECT_EQ(d.at("crosscheck").at("verdict"), "REVIEW");
  EXPECT_EQ(d.at("crosscheck").at("failures").at(0).at("term"), "accel_bias_mps2[1]");
  EXPECT_EQ(d.at("calibrations").size(), 2u);
}

// Issue #19 item 11: the CSV export lacked the gap diagnosis the JSON export carries.
TEST(ExportDiagnosis, CsvCarriesTheStoredDiagnosisAsTheJsonDoes) {
  TempDir dir;
  SqliteRepository repo(dir.file("d.db"));
  const RunId id = repo.create_run(test::new_run("SIM-D", kT0Export));
  RunCompletion c = test::pass_completion(1, kT0Export + kDay / 100);
  c.state = RunState::kReview;
  c.reasons = {{"gap", "sim-to-real gap: explained by accel_quadratic_k2 or accel_asymmetry"}};
  c.diagnosis_json =
      R"({"verdict":"explained","summary":"explained by accel_quadratic_k2 or accel_asymmetry, \"equally\"",)"
      R"("explained_by":["accel_quadratic_k2","accel_asymmetry"],"best":null,)"
      R"("overall":{"gap":49.037,"p_value":0},"held_out":{"gap_before":84.2,"gap_after":1.009}})";
  repo.finish_run(id, c);
  std::ostringstream csv, js;
  export_csv(repo, {}, csv);
  export_json(repo, {}, js);
  const auto rows = parse_csv(csv.str());
  ASSERT_EQ(rows.size(), 3u);  // header, ains, nlsq
  std::map<std::string, std::size_t> col;
  for (std::size_t i = 0; i < rows[0].size(); ++i) col[rows[0][i]] = i;
  const json d = json::parse(js.str())[0].at("diagnosis");
  for (std::size_t r = 1; r < rows.size(); ++r) {
    const auto& row = rows[r];
    EXPECT_EQ(row[col.at("diagnosis.verdict")], d.at("verdict"));
    EXPECT_EQ(row[col.at("diagnosis.summary")], d.at("summary"));
    EXPECT_EQ(row[col.at("diagnosis.explained_by")], "accel_quadratic_k2|accel_asymmetry");
    EXPECT_EQ(row[col.at("diagnosis.best.effect")], "");
    EXPECT_DOUBLE_EQ(std::stod(row[col.at("diagnosis.overall.gap")]),
                     d["overall"]["gap"].get<double>());
    EXPECT_DOUBLE_EQ(std::stod(row[col.at("diagnosis.held_out.gap_after")]),
                     d["held_out"]["gap_after"].get<double>());
  }
}

TEST(CsvField, QuotesOnlyWhenNeededAndDoublesQuotes) {
  EXPECT_EQ(csv_field("plain"), "plain");
  EXPECT_EQ(csv_field(""), "");
  EXPECT_EQ(csv_field("a,b"), "\"a,b\"");
  EXPECT_EQ(csv_field("say \"hi\""), "\"say \"\"hi\"\"\"");
  EXPECT_EQ(csv_field("two\nlines"), "\"two\nlines\"");
  EXPECT_EQ(csv_field("cr\r"), "\"cr\r\"");
}

}  // namespace
}  // namespace imucal::db
