#pragma once
// `imucal check CALIBRATION DIR` and `imucal apply CALIBRATION DIR --out OUTDIR` (issue #48 item
// 6): a calibration judged on, and applied to, another recording of the same unit.
//  * CALIBRATION is a parameter-set JSON file (ARCHITECTURE §3; `stationctl params` prints one) or
//    what `imucal calibrate --json` prints — then the method whose result passed its limits (AINS
//    when several did: the station's active set), or `--method NAME`. A run archive holds no
//    calibration result (db/archive/FORMAT.md), so a directory is refused saying how to get one.
//  * check: the held-out check (calib/checks/held_out_check.hpp) on DIR — per rest |f| − g, per
//    move the gravity carried by the gyros against the gravity seen, uncompensated (nominal
//    values) beside compensated, and their RMS.
//  * apply: DIR's archive with its IMU increments compensated by the parameters (the inverse of
//    eq. 18 and 23), written atomically to OUTDIR, which must not exist. truth.json is not
//    carried (it describes the uncompensated unit), nor is a daemon run's capture.log.
// Bad input is one line naming the file and the problem; nothing is written.
#include <CLI/CLI.hpp>
#include <string>

namespace imucal::tools::imucal {

struct CheckArgs {
  std::string calibration, dir;
  std::string method;       ///< --method: which result of a calibrate --json file; empty = passed
  std::string grade;        ///< --grade: instead of run.toml's [prior] grade; empty = run.toml's
  double min_rest_s = 0.0;  ///< --min-rest-s (field runs); 0 = run.toml's
  std::string out_dir;      ///< apply --out
  bool json = false;
};

/// Adds `check` to `app`, binding its options to `args`.
CLI::App* add_check_command(CLI::App& app, CheckArgs& args);
/// Adds `apply` to `app`, binding its options to `args`.
CLI::App* add_apply_command(CLI::App& app, CheckArgs& args);
/// Run them. Exit 0 done; bad input throws (main prints it, exit 1).
int cmd_check(const CheckArgs& args);
int cmd_apply(const CheckArgs& args);

}  // namespace imucal::tools::imucal
