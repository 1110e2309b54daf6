// station::run::ArchiveWriter, recover_archive, archive_digest and run.toml [capture]: the archive
// written as the run goes reads back bit-exactly with db/archive's reader; a writer killed with
// SIGKILL at an arbitrary moment leaves an archive that recover_archive() turns into a readable one
// holding exactly a prefix of what was written; torn and garbage tails are cut; the digest sees
// every byte; the [capture] section round-trips and is parsed strictly.
#include "station/run/archive_writer.hpp"

#include <gtest/gtest.h>
#include <signal.h>
#include <stdlib.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <thread>

#include "calib/core/conventions.hpp"
#include "calib/core/site_presets.hpp"
#include "db/archive/archive_error.hpp"
#include "db/archive/archive_input.hpp"
#include "db/archive/io_util.hpp"
#include "db/archive/run_archive.hpp"
#include "drivers/imu/candump_log.hpp"
#include "drivers/imu/imu_codec.hpp"
#include "sequences/library.hpp"
#include "station/run/capture_stats.hpp"
#include "tests/support/temp_dir.hpp"

namespace imucal::station {
using namespace imucal::station::run;
namespace {

namespace fs = std::filesystem;

/// This file's temporary directories.
class TempDir : public test_support::ScopedTempDir {
 public:
  TempDir() : ScopedTempDir("imucal_archive_writer_test") {}
};

constexpr double kRate_hz = 100.0;

db::archive::RunInfo make_info() {
  db::archive::RunInfo ri;
  ri.serial = "SIM-0001";
  ri.station_name = "test bay";
  ri.site = calib::core::demo_factory_site();
  ri.imu_rate_hz = kRate_hz;
  ri.software_version = "0.1.0";
  ri.start_time = "2026-11-22T03:00:00Z";
  ri.sequence_name = "short";
  return ri;
}

// Row k of a synthetic run: the unit resting level (f_b = (0, 0, -g), NED down = body z at zero
// angles) with small, irregular increments so that every digit of the text matters; every 5th
// block of 40 rows is moving (at_rest = 0).
calib::core::ImuIncrement imu_row(uint64_t k) {
  calib::core::ImuIncrement s;
  s.t_s = static_cast<double>(k + 1) / kRate_hz;
  s.dt_s = 1.0 / kRate_hz;
  const double x = static_cast<double>(k % 97) - 48.0;
  s.dtheta_rad = Eigen::Vector3d(x * 1.0e-9 / 3.0, 7.29e-7 + x * 1e-11, -x * 2.5e-10 / 7.0);
  s.dv_mps = Eigen::Vector3d(x * 1e-7 / 3.0, 1e-6 + x * 3e-8, -9.815 / kRate_hz + x * 1e-9 / 7.0);
  return s;
}
calib::core::TableSample table_row(uint64_t k) {
  const double outer_deg = static_cast<double>(k % 360) + 0.125 / 3.0;
  const double inner_deg = -static_cast<double>(k % 180) / 7.0;
  return {static_cast<double>(k + 1) / kRate_hz, outer_deg * kDegToRad, inner_deg * kDegToRad,
          (k / 40) % 5 != 4};
}
// Frame j of the synthetic capture.log.
drivers::imu::ReceivedFrame frame_of(uint64_t j) {
  drivers::imu::ReceivedFrame f;
  f.frame.can_id = 0x100 + static_cast<uint32_t>(j % 4);
  f.frame.len = 8;
  for (int b = 0; b < 8; ++b)
    f.frame.data[static_cast<std::size_t>(b)] = static_cast<uint8_t>(j * 31 + b);
  f.rx_time_ns = 1'700'000'000'000'000'000LL + static_cast<int64_t>(j) * 2'500'000;
  return f;
}

bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

void expect_row_equal(const db::archive::RunArchive& a, uint64_t k) {
  const calib::core::ImuIncrement e = imu_row(k);
  const calib::core::ImuIncrement& s = a.imu[k];
  ASSERT_TRUE(same_bits(s.t_s, e.t_s)) << "row " << k;
  for (int i = 0; i < 3; ++i) {
    ASSERT_TRUE(same_bits(s.dtheta_rad(i), e.dtheta_rad(i))) << "row " << k << " dtheta " << i;
    ASSERT_TRUE(same_bits(s.dv_mps(i), e.dv_mps(i))) << "row " << k << " dv " << i;
  }
  const calib::core::TableSample et = table_row(k);
  const calib::core::TableSample& t = a.table[k];
  ASSERT_TRUE(same_bits(t.t_s, et.t_s)) << "row " << k;
  ASSERT_TRUE(same_bits(t.outer_rad, et.outer_rad)) << "row " << k;
  ASSERT_TRUE(same_bits(t.inner_rad, et.inner_rad)) << "row " << k;
  ASSERT_EQ(t.at_rest, et.at_rest) << "row " << k;
}

std::size_t count_lines(const std::string& path) {
  const std::string s = db::archive::read_text_file(path);
  return static_cast<std::size_t>(std::count(s.begin(), s.end(), '\n'));
}

uint64_t expected_rest(uint64_t n) {
  uint64_t r = 0;
  for (uint64_t k = 0; k < n; ++k) r += table_row(k).at_rest ? 1 : 0;
  return r;
}

db::archive::CaptureInfo distinct_capture(bool complete) {
  db::archive::CaptureInfo ci;
  ci.complete = complete;
  uint64_t v = 1;
  for (const auto& c : db::archive::CaptureInfo::counters()) {
    ci.*(c.second) = v * 1000 + v;  // every counter a different value
    ++v;
  }
  ci.frames_received = 9'007'199'254'740'993ULL;  // 2^53 + 1: not representable as a double
  return ci;
}

// ------------------------------------------------------------------------------------------------

TEST(ArchiveWriter, WrittenArchiveReadsBackBitExactAndCalibrationInputBuilds) {
  TempDir tmp;
  const std::string dir = tmp.sub("runs/1-SIM-0001");
  const uint64_t n = 1000;
  {
    ArchiveWriter w(dir, make_info());
    EXPECT_TRUE(fs::exists(dir + "/run.toml"));
    for (uint64_t k = 0; k < n; ++k) {
      w.append_row(imu_row(k), table_row(k));
      for (uint64_t j = 4 * k; j < 4 * k + 4; ++j) w.append_frame(frame_of(j), "can0");
    }
    EXPECT_EQ(w.rows(), n);
    EXPECT_EQ(w.frames(), 4 * n);
    EXPECT_EQ(w.rest_rows(), expected_rest(n));
    db::archive::RunInfo fin = make_info();
    fin.end_time = "2026-11-22T03:00:10Z";
    fin.capture = distinct_capture(true);
    w.finish(fin);
    EXPECT_THROW(w.append_row(imu_row(n), table_row(n)), std::logic_error);
  }
  const db::archive::RunArchive a = db::archive::read_archive(dir);
  ASSERT_EQ(a.imu.size(), n);
  ASSERT_EQ(a.table.size(), n);
  for (uint64_t k = 0; k < n; ++k) expect_row_equal(a, k);
  EXPECT_TRUE(std::isnan(a.imu[0].temp_c));
  EXPECT_EQ(a.info.serial, "SIM-0001");
  EXPECT_EQ(a.info.end_time, "2026-11-22T03:00:10Z");
  ASSERT_TRUE(a.info.capture.has_value());
  EXPECT_EQ(*a.info.capture, distinct_capture(true));
  const calib::core::CalibrationInput in = db::archive::to_calibration_input(a);
  EXPECT_EQ(in.imu.size(), n);
  EXPECT_EQ(static_cast<uint64_t>(std::count_if(in.reference.begin(), in.reference.end(),
                                                [](const auto& r) { return r.at_rest; })),
            expected_rest(n));

  // capture.log: every frame, in order, as given.
  drivers::imu::CandumpReader r(dir + "/capture.log");
  drivers::imu::CandumpRecord rec;
  uint64_t j = 0;
  while (r.next(rec)) {
    const drivers::imu::ReceivedFrame e = frame_of(j);
    ASSERT_EQ(rec.frame.frame, e.frame) << "frame " << j;
    ASSERT_EQ(rec.frame.rx_time_ns, e.rx_time_ns) << "frame " << j;  // µs-exact times
    EXPECT_EQ(rec.interface, "can0");
    ++j;
  }
  EXPECT_EQ(j, 4 * n);
  EXPECT_EQ(r.truncated_lines(), 0u);
}

TEST(ArchiveWriter, FlushKeepsImuAndTableInLockstep) {
  TempDir tmp;
  const std::string dir = tmp.sub("run");
  ArchiveWriter w(dir, make_info());
  // The skeleton is on disk at once: headers only, a run.toml without end time or [capture].
  EXPECT_EQ(count_lines(dir + "/imu.csv"), 1u);
  EXPECT_EQ(count_lines(dir + "/table.csv"), 1u);
  const db::archive::RunInfo start =
      db::archive::parse_run_info(db::archive::read_text_file(dir + "/run.toml"), "run.toml");
  EXPECT_TRUE(start.end_time.empty());
  EXPECT_FALSE(start.capture.has_value());
  for (uint64_t k = 0; k < 10; ++k) w.append_row(imu_row(k), table_row(k));
  w.flush();
  EXPECT_EQ(count_lines(dir + "/imu.csv"), 11u);
  EXPECT_EQ(count_lines(dir + "/table.csv"), 11u);
  for (uint64_t k = 10; k < 15; ++k) w.append_row(imu_row(k), table_row(k));
  // Buffered rows are not on disk yet, in neither file.
  EXPECT_EQ(count_lines(dir + "/imu.csv"), 11u);
  EXPECT_EQ(count_lines(dir + "/table.csv"), 11u);
  w.sync();
  EXPECT_EQ(count_lines(dir + "/imu.csv"), 16u);
  EXPECT_EQ(count_lines(dir + "/table.csv"), 16u);
  // An unfinished but flushed archive is already readable.
  const db::archive::RunArchive a = db::archive::read_archive(dir);
  ASSERT_EQ(a.imu.size(), 15u);
  for (uint64_t k = 0; k < 15; ++k) expect_row_equal(a, k);
}

TEST(ArchiveWriter, RefusesBadRowsAndOccupiedDirectories) {
  TempDir tmp;
  const std::string dir = tmp.sub("run");
  {
    ArchiveWriter w(dir, make_info());
    calib::core::TableSample t = table_row(0);
    t.t_s += 1e-3;
    EXPECT_THROW(w.append_row(imu_row(0), t), std::invalid_argument);
    w.append_row(imu_row(1), table_row(1));
    EXPECT_THROW(w.append_row(imu_row(0), table_row(0)), std::invalid_argument);  // time back
    calib::core::ImuIncrement bad = imu_row(2);
    bad.dv_mps(1) = std::nan("");
    EXPECT_THROW(w.append_row(bad, table_row(2)), std::invalid_argument);
    EXPECT_EQ(w.rows(), 1u);
  }
  // The directory now holds an archive: a second writer must not touch it.
  const std::string before = archive_digest(dir);
  try {
    ArchiveWriter w2(dir, make_info());
    FAIL() << "writer accepted a non-empty directory";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(dir), std::string::npos) << e.what();
  }
  EXPECT_EQ(archive_digest(dir), before);
  // An existing empty directory is fine.
  fs::create_directories(tmp.sub("empty"));
  EXPECT_NO_THROW(ArchiveWriter(tmp.sub("empty"), make_info()));
  // An attitude-referenced RunInfo cannot be written by the station (it logs table.csv); nothing
  // is left behind.
  db::archive::RunInfo att = make_info();
  att.reference = db::archive::ReferenceKind::kAttitude;
  EXPECT_THROW(ArchiveWriter(tmp.sub("att"), att), std::runtime_error);
  EXPECT_FALSE(fs::exists(tmp.sub("att")));
}

// The writer process is killed with SIGKILL while it writes; recovery yields a readable archive
// holding exactly the first n rows it was given (n = what recover_archive returns).
TEST(ArchiveWriter, SigkilledWriterIsRecoveredToACommonPrefix) {
  TempDir tmp;
  const std::string dir = tmp.sub("runs/7-SIM-0001");
  for (int attempt = 0; attempt < 3; ++attempt) {
    const std::string d = dir + "-" + std::to_string(attempt);
    const pid_t pid = ::fork();
    ASSERT_GE(pid, 0);
    if (pid == 0) {
      // Child: write as fast as possible, flushing at irregular row counts, until killed.
      try {
        ArchiveWriter w(d, make_info());
        uint64_t j = 0;
        for (uint64_t k = 0; k < 3'000'000; ++k) {
          w.append_row(imu_row(k), table_row(k));
          for (int f = 0; f < 4; ++f) w.append_frame(frame_of(j++), "can0");
          if (k % (13 + attempt * 7) == 0) w.flush();
        }
        ::pause();
      } catch (...) {
        ::_exit(3);
      }
      ::_exit(0);
    }
    // Parent: kill it once a few hundred kB are on disk (a different moment each attempt).
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
    std::error_code ec;
    while (std::chrono::steady_clock::now() < deadline) {
      const auto sz = fs::file_size(d + "/imu.csv", ec);
      if (!ec && sz > 200'000u * static_cast<unsigned>(attempt + 1)) break;
      std::this_thread::sleep_for(std::chrono::microseconds(300 + 700 * attempt));
    }
    ASSERT_EQ(::kill(pid, SIGKILL), 0);
    int status = 0;
    ASSERT_EQ(::waitpid(pid, &status, 0), pid);
    ASSERT_TRUE(WIFSIGNALED(status)) << "writer exited by itself, status " << status;

    const uint64_t n = recover_archive(d, "2026-11-22T04:00:00Z");
    ASSERT_GT(n, 1000u) << "attempt " << attempt;
    const db::archive::RunArchive a = db::archive::read_archive(d);
    ASSERT_EQ(a.imu.size(), n);
    ASSERT_EQ(a.table.size(), n);
    for (uint64_t k = 0; k < n; ++k) expect_row_equal(a, k);
    EXPECT_EQ(a.info.end_time, "2026-11-22T04:00:00Z");
    ASSERT_TRUE(a.info.capture.has_value());
    EXPECT_FALSE(a.info.capture->complete);
    EXPECT_EQ(a.info.capture->rows_written, n);
    EXPECT_EQ(a.info.capture->rest_samples, expected_rest(n));
    EXPECT_NO_THROW(db::archive::to_calibration_input(a));

    // capture.log: a prefix of the frames given, a torn last line tolerated.
    drivers::imu::CandumpReader r(d + "/capture.log");
    drivers::imu::CandumpRecord rec;
    uint64_t j = 0;
    while (r.next(rec)) {
      ASSERT_EQ(rec.frame.frame, frame_of(j).frame) << "frame " << j;
      ++j;
    }
    EXPECT_LE(r.truncated_lines(), 1u);
    EXPECT_GT(j, 0u);
    EXPECT_EQ(a.info.capture->frames_logged, j);

    // Recovery is idempotent: a second pass changes nothing.
    const std::string digest = archive_digest(d);
    EXPECT_EQ(recover_archive(d, "2026-11-22T04:00:00Z"), n);
    EXPECT_EQ(archive_digest(d), digest);
  }
}

TEST(RecoverArchive, CutsTornAndGarbageTailsToTheCommonPrefix) {
  TempDir tmp;
  const std::string dir = tmp.sub("run");
  {
    ArchiveWriter w(dir, make_info());
    for (uint64_t k = 0; k < 100; ++k) w.append_row(imu_row(k), table_row(k));
    for (uint64_t j = 0; j < 10; ++j) w.append_frame(frame_of(j), "can0");
    w.flush();
  }  // destroyed unfinished, like a daemon that died
  auto append = [](const std::string& path, const std::string& text) {
    std::ofstream f(path, std::ios::app | std::ios::binary);
    f << text;
  };
  // imu.csv: two more complete rows and a torn third; table.csv: one more row, then a block of
  // zeros (what a file system without data journaling can show after a power cut).
  const std::string imu_101 = "1.01,1e-09,0,0,0,0,-0.098\n";
  append(dir + "/imu.csv", imu_101 + "1.02,1e-09,0,0,0,0,-0.098\n1.03,2e-0");
  append(dir + "/table.csv", "1.01,0,0,1\n" + std::string(16, '\0') + "\n");
  append(dir + "/capture.log", "(1700000000.123456) can0 10");  // torn, no newline

  const uint64_t n = recover_archive(dir, "2026-11-22T05:00:00Z");
  EXPECT_EQ(n, 101u);
  const db::archive::RunArchive a = db::archive::read_archive(dir);
  ASSERT_EQ(a.imu.size(), 101u);
  for (uint64_t k = 0; k < 100; ++k) expect_row_equal(a, k);
  EXPECT_EQ(a.imu[100].t_s, 1.01);
  EXPECT_EQ(a.imu[100].dtheta_rad(0), 1e-9);
  EXPECT_TRUE(a.table[100].at_rest);
  EXPECT_EQ(count_lines(dir + "/imu.csv"), 102u);
  EXPECT_EQ(count_lines(dir + "/table.csv"), 102u);
  ASSERT_TRUE(a.info.capture.has_value());
  EXPECT_EQ(a.info.capture->frames_logged, 10u);  // the torn 11th line is not a frame
  EXPECT_EQ(a.info.capture->rest_samples, expected_rest(100) + 1);
  // capture.log is raw data: left exactly as it was (torn line included).
  EXPECT_EQ(db::archive::read_text_file(dir + "/capture.log").back(), '0');
}

TEST(RecoverArchive, SkeletonWithoutRowsAndMissingRunToml) {
  TempDir tmp;
  const std::string dir = tmp.sub("run");
  { ArchiveWriter w(dir, make_info()); }
  // Killed before the header reached table.csv: recovery restores it.
  {
    std::ofstream f(dir + "/table.csv", std::ios::trunc);
    f << "t_s,out";
  }
  EXPECT_EQ(recover_archive(dir, "2026-11-22T05:00:00Z"), 0u);
  EXPECT_EQ(db::archive::read_text_file(dir + "/table.csv"), "t_s,outer_deg,inner_deg,at_rest\n");
  // No rows: the reader refuses it with a clear message (nothing to calibrate), naming imu.csv.
  try {
    db::archive::read_archive(dir);
    FAIL() << "empty archive accepted";
  } catch (const db::archive::ArchiveError& e) {
    EXPECT_NE(e.file().find("imu.csv"), std::string::npos) << e.what();
  }
  fs::remove(dir + "/run.toml");
  try {
    recover_archive(dir, "2026-11-22T05:00:00Z");
    FAIL() << "recovered an archive without run.toml";
  } catch (const db::archive::ArchiveError& e) {
    EXPECT_NE(std::string(e.what()).find("run.toml"), std::string::npos) << e.what();
  }
}

TEST(RecoverArchive, LeavesAFinishedArchiveUntouched) {
  TempDir tmp;
  const std::string dir = tmp.sub("run");
  {
    ArchiveWriter w(dir, make_info());
    for (uint64_t k = 0; k < 50; ++k) w.append_row(imu_row(k), table_row(k));
    db::archive::RunInfo fin = make_info();
    fin.end_time = "2026-11-22T03:00:01Z";
    db::archive::CaptureInfo ci = distinct_capture(true);
    ci.rows_written = 50;
    fin.capture = ci;
    w.finish(fin);
  }
  // A stray temporary file of an interrupted rewrite is not part of the archive.
  {
    std::ofstream f(dir + "/run.toml.tmp-AbC123");
    f << "serial = \"x\"\n";
  }
  const std::string run_toml = db::archive::read_text_file(dir + "/run.toml");
  EXPECT_EQ(recover_archive(dir, "2026-11-22T09:00:00Z"), 50u);
  EXPECT_EQ(db::archive::read_text_file(dir + "/run.toml"), run_toml);
  EXPECT_FALSE(fs::exists(dir + "/run.toml.tmp-AbC123"));
}

// ------------------------------------------------------------------------------------- digest

std::string sha256sum_of(const std::string& path) {
  const std::string cmd = "sha256sum '" + path + "'";
  FILE* p = ::popen(cmd.c_str(), "r");
  if (!p) return "";
  char buf[256] = {};
  const std::size_t n = std::fread(buf, 1, sizeof buf - 1, p);
  ::pclose(p);
  return std::string(buf, n).substr(0, 64);
}

TEST(ArchiveDigest, MatchesItsDefinitionAndSeesEveryByte) {
  TempDir tmp;
  const std::string dir = tmp.sub("run");
  {
    ArchiveWriter w(dir, make_info());
    for (uint64_t k = 0; k < 20; ++k) {
      w.append_row(imu_row(k), table_row(k));
      w.append_frame(frame_of(k), "can0");
    }
    db::archive::RunInfo fin = make_info();
    fin.capture = distinct_capture(true);
    w.finish(fin);
  }
  // The definition, with coreutils' sha256sum as an independent hash of each file.
  std::string manifest;
  for (const char* name : {"capture.log", "imu.csv", "run.toml", "table.csv"}) {
    const std::string h = sha256sum_of(dir + "/" + name);
    ASSERT_EQ(h.size(), 64u) << "sha256sum failed on " << name;
    manifest += std::string(name) + "  " + h + "\n";
  }
  const std::string digest = archive_digest(dir);
  EXPECT_EQ(digest, sequences::sha256_hex(manifest));
  EXPECT_EQ(digest.size(), 64u);

  for (const char* name : {"capture.log", "imu.csv", "run.toml", "table.csv"}) {
    const std::string path = dir + "/" + name;
    const std::string orig = db::archive::read_text_file(path);
    for (std::size_t pos : {std::size_t{0}, orig.size() / 2, orig.size() - 1}) {
      std::string changed = orig;
      changed[pos] = static_cast<char>(changed[pos] ^ 0x01);
      {
        std::ofstream f(path, std::ios::trunc | std::ios::binary);
        f << changed;
      }
      EXPECT_NE(archive_digest(dir), digest) << name << " byte " << pos;
    }
    {
      std::ofstream f(path, std::ios::trunc | std::ios::binary);
      f << orig;
    }
    EXPECT_EQ(archive_digest(dir), digest) << name << " restored";
  }
  // A renamed file changes it too (names are part of the manifest).
  fs::rename(dir + "/capture.log", dir + "/capture.log1");
  EXPECT_NE(archive_digest(dir), digest);
}

// ------------------------------------------------------------------------------ [capture] section

const char* kBaseToml =
    "serial = \"S1\"\n"
    "[station]\nlat_deg = 55.0\nlon_deg = 12.0\nheight_m = 10.0\n"
    "[imu]\nrate_hz = 100.0\n";

std::string capture_toml(const std::string& replace_key = "", const std::string& with = "") {
  std::string s = std::string(kBaseToml) + "[capture]\ncomplete = true\n";
  for (const auto& c : db::archive::CaptureInfo::counters()) {
    if (replace_key == c.first) {
      s += with;
      continue;
    }
    s += std::string(c.first) + " = 5\n";
  }
  if (replace_key.empty()) s += with;
  return s;
}

void expect_capture_error(const std::string& text, const std::string& field,
                          const std::string& words) {
  try {
    db::archive::parse_run_info(text, "run.toml");
    FAIL() << "accepted: " << text;
  } catch (const db::archive::ArchiveError& e) {
    EXPECT_EQ(e.field(), field) << e.what();
    EXPECT_NE(std::string(e.what()).find(words), std::string::npos) << e.what();
  }
}

TEST(CaptureSection, RoundTripsExactly) {
  db::archive::RunInfo ri = make_info();
  EXPECT_FALSE(
      db::archive::parse_run_info(db::archive::run_info_text(ri), "x").capture.has_value());
  for (bool complete : {true, false}) {
    ri.capture = distinct_capture(complete);
    const std::string text = db::archive::run_info_text(ri);
    EXPECT_NE(text.find("[capture]"), std::string::npos);
    EXPECT_NE(text.find("frames_received = 9007199254740993\n"), std::string::npos) << text;
    const db::archive::RunInfo back = db::archive::parse_run_info(text, "run.toml");
    ASSERT_TRUE(back.capture.has_value());
    EXPECT_EQ(*back.capture, *ri.capture);
    EXPECT_EQ(back.capture->complete, complete);
    // Every counter is there under its own name with its own value.
    for (const auto& c : db::archive::CaptureInfo::counters())
      EXPECT_EQ((*back.capture).*(c.second), (*ri.capture).*(c.second)) << c.first;
  }
  // Hand-written section with all keys parses.
  const db::archive::RunInfo hand = db::archive::parse_run_info(capture_toml(), "run.toml");
  ASSERT_TRUE(hand.capture.has_value());
  EXPECT_TRUE(hand.capture->complete);
  EXPECT_EQ(hand.capture->max_gap_samples, 5u);
}

TEST(CaptureSection, IsParsedStrictly) {
  expect_capture_error(capture_toml("", "frame_received = 1\n"), "capture.frame_received",
                       "unknown key in [capture]");
  expect_capture_error(capture_toml("rows_written", ""), "capture.rows_written", "missing");
  expect_capture_error(capture_toml("rows_written", "rows_written = 1.0\n"), "capture.rows_written",
                       "expected a non-negative integer, got float");
  expect_capture_error(capture_toml("imu_resets", "imu_resets = -1\n"), "capture.imu_resets",
                       "non-negative");
  expect_capture_error(capture_toml("imu_resets", "imu_resets = \"0\"\n"), "capture.imu_resets",
                       "got string");
  std::string no_complete = capture_toml();
  no_complete.replace(no_complete.find("complete = true\n"), 16, "");
  expect_capture_error(no_complete, "capture.complete", "missing");
  std::string int_complete = capture_toml();
  int_complete.replace(int_complete.find("complete = true"), 15, "complete = 1");
  expect_capture_error(int_complete, "capture.complete", "expected a boolean");
  // The error names the line of the offending key.
  try {
    db::archive::parse_run_info(capture_toml("", "bogus = 1\n"), "run.toml");
    FAIL();
  } catch (const db::archive::ArchiveError& e) {
    const std::string text = capture_toml("", "bogus = 1\n");
    const std::size_t line = static_cast<std::size_t>(
        std::count(text.begin(), text.begin() + static_cast<long>(text.find("bogus")), '\n') + 1);
    EXPECT_EQ(e.line(), line) << e.what();
  }
  expect_capture_error("capture = 3\n" + std::string(kBaseToml), "capture", "expected a table");
}

TEST(CaptureSection, StatsConvertBothWays) {
  const db::archive::CaptureInfo ci = distinct_capture(false);
  const CaptureStats s = capture_stats_from_info(ci);
  EXPECT_EQ(s.frames_received, ci.frames_received);
  EXPECT_EQ(s.rest_samples, ci.rest_samples);
  EXPECT_EQ(s.max_gap_samples, ci.max_gap_samples);
  EXPECT_EQ(to_capture_info(s, false), ci);
  EXPECT_NE(to_capture_info(s, true), ci);
}

// Issue #10: a recovered run's capture counters add up (frames_received = frames_logged, the
// decoder's counters recounted from capture.log) instead of showing 0 received beside N logged.
TEST(RecoverArchive, RecountsTheDecoderCountersFromTheCaptureLog) {
  TempDir tmp;
  const std::string dir = tmp.sub("run");
  drivers::imu::ImuFrameEncoder enc;
  uint64_t logged = 0;
  {
    ArchiveWriter w(dir, make_info());
    int64_t t_ns = 1'700'000'000'000'000'000LL;
    for (uint64_t k = 0; k < 50; ++k) {
      w.append_row(imu_row(k), table_row(k));
      calib::core::ImuIncrement inc;
      inc.dt_s = 0.01;
      inc.dv_mps = Eigen::Vector3d(0, 0, -0.098);
      const auto frames = enc.encode(inc);
      if (k == 20) continue;  // sample 20 lost on the bus: a gap of one
      for (std::size_t p = 0; p < frames.size(); ++p) {
        drivers::imu::ReceivedFrame f;
        f.frame = frames[p];
        f.rx_time_ns = (t_ns += 2'500'000);
        w.append_frame(f, "can0");
        ++logged;
        if (k == 30 && p == 1) {  // one frame seen twice
          w.append_frame(f, "can0");
          ++logged;
        }
      }
    }
    w.flush();
  }  // destroyed unfinished, like a daemon that died

  ASSERT_EQ(recover_archive(dir, "2026-11-25T05:00:00Z"), 50u);
  const db::archive::RunArchive a = db::archive::read_archive(dir);
  ASSERT_TRUE(a.info.capture.has_value());
  const db::archive::CaptureInfo& c = *a.info.capture;
  EXPECT_FALSE(c.complete);
  EXPECT_EQ(c.frames_logged, logged);
  EXPECT_EQ(c.frames_received, logged);
  EXPECT_EQ(c.samples_decoded, 49u);
  EXPECT_EQ(c.samples_lost, 1u);
  EXPECT_EQ(c.max_gap_samples, 1u);
  EXPECT_EQ(c.frames_duplicate, 1u);
  EXPECT_EQ(c.samples_corrupt, 0u);
  EXPECT_EQ(c.rows_written, 50u);
}

}  // namespace
}  // namespace imucal::station
