// Several units on one table run (issue #23 item 1), end to end: stationsim simulates up to four
// units on its table (each its own bus, truth, noise, mounting and lever arm), stationd captures
// them concurrently and calibrates them in parallel, each into its own archive and run under its
// own serial. What it must show: four PASS rows, each unit's parameters within 4 σ of its own
// truth and with the σ of a one-unit run (within 5 %); one unit's stream cut mid-run fails that
// unit alone; an abort ends them all; table time per unit ≤ 0.3 of a one-unit run.
//
// The σ of a one-unit run takes a factory-std run of its own per slot. The whole count
// (IMUCAL_WHOLE_COUNTS=1) makes all four; ctest two, slots A and B: B is A turned 90° (other body
// axes out, the case where σ moves), C and D are A and B turned 180° (the same axes informed). A
// four-unit σ off by more than 5 % on A or B fails either count; on C or D alone, only the whole.
#include <cmath>

#include "calib/sim/truth_sim.hpp"
#include "db/archive/param_json.hpp"
#include "db/archive/run_archive.hpp"
#include "db/archive/unit_file.hpp"
#include "tests/e2e/station_harness.hpp"
#include "tests/support/ci_count.hpp"

namespace imucal::e2e {
namespace {

/// A fixture slot of the test station: its mounting on the platform and its unit.
struct Slot {
  std::string name;
  std::string mount_rpy;  ///< "R/P/Y" deg
  std::string lever;      ///< "X/Y/Z" m, platform axes
};

// Four slots around the rotation centre, each turned so that a different body axis points out.
const std::vector<Slot> kSlots = {{"A", "0/0/0", "0.12/0/0.04"},
                                  {"B", "0/0/90", "0/0.12/0.04"},
                                  {"C", "0/0/180", "-0.12/0/0.04"},
                                  {"D", "0/0/-90", "0/-0.12/0.04"}};

std::string toml_vector(const std::string& slashed) {
  std::string s = "[" + slashed + "]";
  for (char& c : s)
    if (c == '/') c = ',';
  return s;
}

/// Unit i: the default unit with its sensor errors permuted, rescaled and sign-flipped, so that no
/// two units on the fixture share a truth (the table's misalignment is the table's: common).
calib::effects::UnitModel unit_of(int i) {
  calib::effects::UnitModel u = calib::effects::default_unit();
  const double k = 1.0 + 0.35 * i, sign = i % 2 ? -1.0 : 1.0;
  calib::core::ParamSet& p = u.params;
  p.accel_bias_mps2 = sign * k *
                      Eigen::Vector3d(p.accel_bias_mps2(i % 3), p.accel_bias_mps2((i + 1) % 3),
                                      p.accel_bias_mps2((i + 2) % 3));
  p.gyro_bias_radps = -sign * k *
                      Eigen::Vector3d(p.gyro_bias_radps((i + 2) % 3), p.gyro_bias_radps(i % 3),
                                      p.gyro_bias_radps((i + 1) % 3));
  p.accel_M = (i % 2 ? Eigen::Matrix3d(p.accel_M.transpose()) : p.accel_M) * k;
  p.gyro_M = (i % 2 ? p.gyro_M : Eigen::Matrix3d(p.gyro_M.transpose())) * (sign * k);
  return u;
}

class MultiUnitStation {
 public:
  /// stationsim with `n` units (slot i: unit_of(i), its mounting and lever arm; `extra[i]` added to
  /// its --also items, e.g. ",cut=300"), stationd with the matching [[imu]] slots.
  bool start(int n, const std::vector<std::string>& extra = {}) {
    SimOptions o;
    o.seed = 31;
    for (int i = 0; i < n; ++i) {
      const std::string unit_file = st.path("unit-" + kSlots[i].name + ".toml");
      db::archive::write_unit_file(unit_file, unit_of(i));
      const std::string more = i < static_cast<int>(extra.size()) ? extra[i] : "";
      if (i == 0) {
        o.extra.insert(o.extra.end(), {"--unit", unit_file, "--mount", kSlots[0].mount_rpy,
                                       "--lever-arm", kSlots[0].lever});
        if (!more.empty()) o.extra.insert(o.extra.end(), {"--cut-stream-at", more});
        continue;
      }
      o.extra.insert(o.extra.end(),
                     {"--also", bus(i) + ",unit=" + unit_file + ",truth=" + truth(i) +
                                    ",mount=" + kSlots[i].mount_rpy + ",lever=" + kSlots[i].lever +
                                    (more.empty() ? "" : ",cut=" + more)});
    }
    if (!st.start_sim(o)) return false;
    std::string text = st.config_text();
    const auto at = text.find("[imu]\n");
    const auto end = text.find("\n[calibration]");
    std::string imus;
    for (int i = 0; i < n; ++i)
      imus += "[[imu]]\nslot = \"" + kSlots[i].name + "\"\ncan = \"unixcan:" + bus(i) +
              "\"\nmount_rpy_deg = " + toml_vector(kSlots[i].mount_rpy) +
              "\nlever_arm_m = " + toml_vector(kSlots[i].lever) + "\n";
    text = text.substr(0, at) + imus + text.substr(end);
    // Poll the table often: at 200x a 50 ms poll is 10 s of table time between a move's end and
    // the rest it starts, unaided data whose length varies from run to run (and the σ with it).
    const auto ep = text.find("endpoint = ");
    text.insert(text.find('\n', ep) + 1, "poll_period_ms = 5\n");
    st.write_config(text);
    return st.start_daemon();
  }
  std::string bus(int i) const {
    return i == 0 ? st.bus_path() : st.path("bus-" + kSlots[i].name + ".sock");
  }
  std::string truth(int i) const {
    return i == 0 ? st.truth_path() : st.path("truth-" + kSlots[i].name + ".json");
  }

  Station st;
};

/// The stored active parameters of `serial` with their σ.
struct Stored {
  calib::core::ParamVector x, sigma;
};
Stored stored_params(const Station& st, const std::string& serial) {
  const CmdResult r = st.ctl({"--json", "params", serial});
  EXPECT_EQ(r.exit_code, 0) << r.describe();
  const std::string file = st.path("params-" + serial + ".json");
  write_text(file, r.out);
  calib::core::ParamSet sigma;
  const calib::core::ParamSet est = db::archive::read_param_file(file, &sigma);
  return {est.to_vector(), sigma.to_vector()};
}

/// Parameters outside 4 σ of the truth (each printed).
int outside_four_sigma(const Stored& s, const db::archive::Truth& truth, const std::string& who) {
  const calib::core::ParamVector x_true = truth.params.to_vector();
  int outside = 0;
  for (int k = 0; k < calib::core::ParamSet::kSize; ++k) {
    const double z = (s.x[k] - x_true[k]) / s.sigma[k];
    if (!(std::abs(z) <= 4.0)) {
      ++outside;
      ADD_FAILURE() << who << " " << calib::core::param_info(k).name << ": " << z
                    << " sigma from its truth";
    }
  }
  return outside;
}

std::vector<std::string> serials(int n, const std::string& prefix) {
  std::vector<std::string> s;
  for (int i = 0; i < n; ++i) s.push_back(prefix + kSlots[i].name);
  return s;
}

CmdResult start_units(const Station& st, const std::vector<std::string>& sns,
                      const std::string& sequence, std::chrono::milliseconds timeout) {
  std::vector<std::string> args = {"run",        "start", "--sequence", sequence,
                                   "--operator", "e2e",   "--wait"};
  for (const std::string& sn : sns) args.insert(args.end(), {"--serial", sn});
  return st.ctl(args, timeout);
}

TEST(StationMultiUnit, FourUnitsOnOneFactoryStdRunEachPassWithinFourSigmaOfItsOwnTruth) {
  MultiUnitStation m;
  ASSERT_TRUE(m.start(4));
  Station& st = m.st;
  const auto sns = serials(4, "MU-");
  const CmdResult run = start_units(st, sns, "factory-std", 900s);
  ASSERT_EQ(run.exit_code, 0) << run.describe() << "\ndaemon log:\n" << st.daemon_log();
  // The progress line names the other units of the table run.
  EXPECT_NE(run.err.find("B MU-B"), std::string::npos) << run.describe();

  std::vector<long long> ids;
  std::vector<Stored> four;
  double span4_s = 0;
  for (int i = 0; i < 4; ++i) {
    const json rec = newest_run(st, sns[i]);
    ASSERT_TRUE(rec.is_object()) << sns[i];
    EXPECT_EQ(rec.value("state", ""), "done") << rec.dump(2);
    EXPECT_EQ(rec["verdict"], json("PASS")) << rec.dump(2);
    EXPECT_EQ(rec.value("slot", ""), kSlots[i].name);
    ids.push_back(rec.value("run_id", -1LL));
    if (i > 0) {
      EXPECT_EQ(rec["table_run"], json(ids.front())) << "siblings name the table run";
    }
    // Each archive is complete on its own: its serial, slot, mounting, the shared table log.
    const db::archive::RunArchive a = db::archive::read_archive(rec.value("archive_path", ""));
    EXPECT_EQ(a.info.serial, sns[i]);
    EXPECT_EQ(a.info.table.slot, kSlots[i].name);
    EXPECT_FALSE(a.table.empty());
    EXPECT_GT(a.info.table.lever_arm_m.norm(), 0.1);
    if (i == 0) span4_s = db::archive::data_span_s(a);
    // No frame lost at four times a unit's frame rate: the counters the daemon kept per unit.
    ASSERT_TRUE(rec.contains("capture") && rec["capture"].is_object()) << rec.dump(2);
    for (const char* k : {"samples_lost", "samples_filled", "frames_error", "samples_corrupt"})
      EXPECT_EQ(num(rec["capture"], k), 0.0) << sns[i] << " " << k << ": " << rec["capture"].dump();
    EXPECT_GT(num(rec["capture"], "samples_decoded"), 2.2e5) << rec["capture"].dump();
    four.push_back(stored_params(st, sns[i]));
    EXPECT_EQ(outside_four_sigma(four.back(), db::archive::read_truth_json(m.truth(i)), sns[i]), 0);
  }
  // The truths differ: a unit calibrated as its neighbour would fail the check above.
  EXPECT_GT((db::archive::read_truth_json(m.truth(0)).params.to_vector() -
             db::archive::read_truth_json(m.truth(1)).params.to_vector())
                .cwiseAbs()
                .maxCoeff(),
            1e-5);

  // Each slot alone: the σ of a one-unit run in the same mounting (a slot turned by 90° swaps which
  // body axes the sequence informs, so σ is compared slot by slot), and its table time.
  double worst = 0, span1_s = 0;
  const int slots_alone = test_support::whole_counts() ? 4 : 2;
  for (int i = 0; i < slots_alone; ++i) {
    const std::string sn = sns[i] + "1";
    const CmdResult one = st.ctl({"run", "start", "--slot", kSlots[i].name + "=" + sn, "--sequence",
                                  "factory-std", "--wait"},
                                 600s);
    ASSERT_EQ(one.exit_code, 0) << one.describe();
    const Stored alone = stored_params(st, sn);
    for (int k = 0; k < calib::core::ParamSet::kSize; ++k)
      worst = std::max(worst, std::abs(four[i].sigma[k] / alone.sigma[k] - 1.0));
    if (i == 0) {
      const json rec1 = newest_run(st, sn);
      EXPECT_EQ(rec1.value("table_run", json()), json()) << "a unit alone has no table run";
      span1_s = db::archive::data_span_s(db::archive::read_archive(rec1.value("archive_path", "")));
    }
  }
  std::fprintf(stderr,
               "[e2e] four units: largest sigma difference to the same slot alone %.2f %% (%d "
               "slots)\n",
               100 * worst, slots_alone);
  EXPECT_LE(worst, 0.05);
  const double per_unit = span4_s / 4.0 / span1_s;
  std::fprintf(stderr, "[e2e] table time: %.0f s for four units, %.0f s for one: %.3f per unit\n",
               span4_s, span1_s, per_unit);
  EXPECT_LE(per_unit, 0.3);
}

TEST(StationMultiUnit, AStreamCutMidRunFailsThatUnitAloneTheOthersPass) {
  MultiUnitStation m;
  ASSERT_TRUE(m.start(4, {"", "", "120"}));  // slot C's cable pulled 120 s into the capture
  Station& st = m.st;
  const auto sns = serials(4, "CUT-");
  const CmdResult run = start_units(st, sns, "short", 300s);
  EXPECT_NE(run.exit_code, 0) << "one unit failed: the command does not exit 0\n" << run.describe();
  for (int i = 0; i < 4; ++i) {
    const json rec = newest_run(st, sns[i]);
    ASSERT_TRUE(rec.is_object()) << sns[i];
    if (i == 2) {
      EXPECT_EQ(rec.value("state", ""), "failed") << rec.dump(2);
      EXPECT_NE(rec.value("failure_reason", "").find("capture:"), std::string::npos) << rec.dump(2);
      // Its archive is kept and says it is incomplete.
      const db::archive::RunArchive a = db::archive::read_archive(rec.value("archive_path", ""));
      ASSERT_TRUE(a.info.capture.has_value());
      EXPECT_FALSE(a.info.capture->complete);
    } else {
      EXPECT_EQ(rec.value("state", ""), "done") << rec.dump(2);
      EXPECT_EQ(rec["verdict"], json("PASS")) << rec.dump(2);
      EXPECT_EQ(outside_four_sigma(stored_params(st, sns[i]),
                                   db::archive::read_truth_json(m.truth(i)), sns[i]),
                0);
    }
  }
}

TEST(StationMultiUnit, AnAbortEndsEveryUnitAndSlotsAreChecked) {
  MultiUnitStation m;
  ASSERT_TRUE(m.start(2));
  Station& st = m.st;
  // Refused before anything starts: a slot the fixture lacks, a serial twice, --serial with --slot.
  const CmdResult bad_slot = st.ctl({"run", "start", "--slot", "E=X-1"});
  EXPECT_EQ(bad_slot.exit_code, 2) << bad_slot.describe();
  EXPECT_NE(bad_slot.err.find("no slot \"E\""), std::string::npos) << bad_slot.describe();
  const CmdResult twice = st.ctl({"run", "start", "--serial", "X-1", "--serial", "X-1"});
  EXPECT_EQ(twice.exit_code, 2) << twice.describe();
  const CmdResult three =
      st.ctl({"run", "start", "--serial", "X-1", "--serial", "X-2", "--serial", "X-3"});
  EXPECT_EQ(three.exit_code, 2) << three.describe();
  EXPECT_NE(three.err.find("2 slot(s)"), std::string::npos) << three.describe();
  EXPECT_EQ(stored_run_total(st.db_path()), 0);

  const CmdResult started = st.ctl({"--json", "run", "start", "--slot", "B=AB-2", "--slot",
                                    "A=AB-1", "--sequence", "factory-std"});
  ASSERT_EQ(started.exit_code, 0) << started.describe();
  const json live =
      st.wait_live_run([](const json& r) { return r.value("state", "") == "running"; }, 60s);
  ASSERT_TRUE(live.is_object());
  ASSERT_TRUE(live.contains("units")) << live.dump(2);
  EXPECT_EQ(live["units"].size(), 2u);
  const CmdResult status = st.ctl({"run", "status"});
  EXPECT_NE(status.out.find("also on the table: run"), std::string::npos) << status.describe();
  const CmdResult ab = st.ctl({"run", "abort", "--reason", "fixture loose"});
  ASSERT_EQ(ab.exit_code, 0) << ab.describe();
  ASSERT_TRUE(wait_until([&] { return st.live_run().is_null(); }, 60s));
  for (const char* sn : {"AB-1", "AB-2"}) {
    const json rec = newest_run(st, sn);
    EXPECT_EQ(rec.value("state", ""), "aborted") << rec.dump(2);
    EXPECT_EQ(rec.value("failure_reason", ""), "fixture loose") << rec.dump(2);
  }
  EXPECT_EQ(newest_run(st, "AB-2").value("slot", ""), "B");
}

}  // namespace
}  // namespace imucal::e2e
