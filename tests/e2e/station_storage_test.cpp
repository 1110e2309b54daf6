// Storage faults (issue #10): the data disk fills up during a run, or is read-only. The run must
// end FAILED at once with the real reason (ENOSPC writing the archive), `--wait` must return, the
// daemon must keep serving reads, nothing half-written may be marked good, and the station must
// work again when space returns. Real processes; the data directory is a small tmpfs mounted by
// the test (it runs as root, as the CI job does).
#include <sys/mount.h>

#include "tests/e2e/station_harness.hpp"

namespace imucal::e2e {
namespace {

/// A tmpfs of `size` mounted on `dir` for the test's lifetime.
class SmallDisk {
 public:
  SmallDisk(const std::string& dir, const std::string& size) : dir_(dir) {
    fs::create_directories(dir);
    const std::string opts = "size=" + size + ",mode=0755";
    mounted_ = ::mount("tmpfs", dir.c_str(), "tmpfs", 0, opts.c_str()) == 0;
    if (!mounted_) error_ = std::strerror(errno);
  }
  ~SmallDisk() {
    if (mounted_) ::umount2(dir_.c_str(), MNT_DETACH);
  }
  bool mounted() const { return mounted_; }
  const std::string& error() const { return error_; }
  bool resize(const std::string& size) {
    const std::string opts = "size=" + size + ",mode=0755";
    return ::mount("tmpfs", dir_.c_str(), "tmpfs", MS_REMOUNT, opts.c_str()) == 0;
  }
  bool read_only(bool ro) {
    if (::mount("tmpfs", dir_.c_str(), "tmpfs", MS_REMOUNT | (ro ? MS_RDONLY : 0), nullptr) == 0)
      return true;
    error_ = std::strerror(errno);
    return false;
  }

 private:
  std::string dir_;
  bool mounted_ = false;
  std::string error_;
};

TEST(StationStorage, DataDiskFullDuringARunFailsItAtOnceWithTheRealReason) {
  ASSERT_EQ(geteuid(), 0u) << "mounting a tmpfs needs root";
  Station st;
  SmallDisk disk(st.data_dir(), "3m");
  ASSERT_TRUE(disk.mounted()) << "mount tmpfs: " << disk.error();
  ASSERT_TRUE(st.start());
  const auto t0 = std::chrono::steady_clock::now();
  const CmdResult run =
      st.ctl({"run", "start", "--serial", "SIM-0700", "--sequence", "short", "--wait"}, 300s);
  const double took_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_EQ(run.exit_code, 1) << run.describe();
  EXPECT_NE((run.out + run.err).find("No space left on device"), std::string::npos)
      << run.describe();
  EXPECT_LT(took_s, 120.0) << "the run did not end at once";
  // The database says FAILED with the reason; nothing is marked good.
  const CmdResult hist = st.ctl({"--json", "history", "SIM-0700"});
  ASSERT_EQ(hist.exit_code, 0) << hist.describe();
  const json runs = hist.json_out()["runs"];
  ASSERT_EQ(runs.size(), 1u) << hist.describe();
  EXPECT_EQ(runs[0].value("state", ""), "failed") << runs.dump(2);
  EXPECT_NE(runs[0].dump().find("No space left on device"), std::string::npos) << runs.dump(2);
  const CmdResult params = st.ctl({"params", "SIM-0700"});
  EXPECT_NE(params.exit_code, 0) << "a failed run gave the unit active parameters\n"
                                 << params.describe();
  // Space returns: the next run works.
  ASSERT_TRUE(disk.resize("200m"));
  const CmdResult again =
      st.ctl({"run", "start", "--serial", "SIM-0701", "--sequence", "short", "--wait"}, 300s);
  EXPECT_EQ(again.exit_code, 0) << again.describe();
}

/// The station's config with the database on the data disk (its default place).
void database_on_the_data_disk(Station& st) {
  std::string text = st.config_text();
  const std::string from = "database = \"" + st.db_path() + "\"";
  const auto at = text.find(from);
  ASSERT_NE(at, std::string::npos);
  text.replace(at, from.size(), "database = \"" + st.data_dir() + "/history.sqlite\"");
  st.write_config(text);
}

// The database shares the full disk (its default place, <data_dir>/history.sqlite): the run must
// still end FAILED with the real reason, `--wait` must return, reads must go on, and the real
// reason must survive a restart of the daemon before space returns.
TEST(StationStorage, DiskFullWithTheDatabaseOnItEndsTheRunAndKeepsTheReason) {
  ASSERT_EQ(geteuid(), 0u) << "mounting a tmpfs needs root";
  Station st;
  SmallDisk disk(st.data_dir(), "3m");
  ASSERT_TRUE(disk.mounted()) << "mount tmpfs: " << disk.error();
  ASSERT_TRUE(st.start_sim());
  database_on_the_data_disk(st);
  ASSERT_TRUE(st.start_daemon());
  const CmdResult run =
      st.ctl({"run", "start", "--serial", "SIM-0710", "--sequence", "short", "--wait"}, 180s);
  EXPECT_EQ(run.exit_code, 1) << run.describe();
  EXPECT_NE((run.out + run.err).find("No space left on device"), std::string::npos)
      << run.describe();
  const CmdResult status = st.ctl({"--json", "run", "status"});
  EXPECT_EQ(status.exit_code, 0) << status.describe();
  // Reads go on (the daemon serves them from the database it still reads).
  const CmdResult hist = st.ctl({"--json", "history", "SIM-0710"});
  EXPECT_EQ(hist.exit_code, 0) << hist.describe();
  // Restart before space returns: recovery keeps the real reason.
  st.daemon().terminate();
  ASSERT_TRUE(st.start_daemon());
  const CmdResult after = st.ctl({"--json", "history", "SIM-0710"});
  ASSERT_EQ(after.exit_code, 0) << after.describe();
  const json runs = after.json_out()["runs"];
  ASSERT_EQ(runs.size(), 1u) << after.describe();
  EXPECT_EQ(runs[0].value("state", ""), "failed") << runs.dump(2);
  EXPECT_NE(runs[0].dump().find("No space left on device"), std::string::npos) << runs.dump(2);
  // Space returns: the next run works.
  ASSERT_TRUE(disk.resize("200m"));
  const CmdResult again =
      st.ctl({"run", "start", "--serial", "SIM-0711", "--sequence", "short", "--wait"}, 300s);
  EXPECT_EQ(again.exit_code, 0) << again.describe();
}

// A read-only archive disk (a disk holding the daemon's open database or lock file cannot be
// remounted read-only under it): the run fails with the reason, nothing is marked good, reads go
// on, and the station works again once the disk is writable.
TEST(StationStorage, ReadOnlyDataDiskRefusesRunsAndRecovers) {
  ASSERT_EQ(geteuid(), 0u) << "mounting a tmpfs needs root";
  Station st;
  SmallDisk disk(st.data_dir() + "/runs", "200m");  // the daemon's lock file is one level up
  ASSERT_TRUE(disk.mounted()) << "mount tmpfs: " << disk.error();
  ASSERT_TRUE(st.start());
  const CmdResult first =
      st.ctl({"run", "start", "--serial", "SIM-0720", "--sequence", "short", "--wait"}, 300s);
  ASSERT_EQ(first.exit_code, 0) << first.describe();
  ASSERT_TRUE(disk.read_only(true)) << disk.error();
  const CmdResult refused =
      st.ctl({"run", "start", "--serial", "SIM-0721", "--sequence", "short", "--wait"}, 120s);
  EXPECT_NE(refused.exit_code, 0) << refused.describe();
  EXPECT_TRUE(contains_ci(refused.out + refused.err, "read-only") ||
              contains_ci(refused.out + refused.err, "readonly"))
      << refused.describe();
  const CmdResult hist = st.ctl({"--json", "history", "SIM-0720"});
  EXPECT_EQ(hist.exit_code, 0) << hist.describe();
  ASSERT_TRUE(disk.read_only(false));
  const CmdResult again =
      st.ctl({"run", "start", "--serial", "SIM-0722", "--sequence", "short", "--wait"}, 300s);
  EXPECT_EQ(again.exit_code, 0) << again.describe();
  // Whether refused at the start or failed at once: never good.
  const CmdResult params = st.ctl({"--json", "history", "SIM-0721"});
  if (params.exit_code == 0) {
    const json runs = params.json_out()["runs"];  // a copy: the range-for must not outlive it
    for (const auto& r : runs) EXPECT_NE(r.value("state", ""), "done") << r.dump(2);
  }
}

}  // namespace
}  // namespace imucal::e2e
