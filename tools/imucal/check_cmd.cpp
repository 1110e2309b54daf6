#include "tools/imucal/check_cmd.hpp"

#include <cstdio>
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <vector>

#include "calib/checks/held_out_check.hpp"
#include "calib/core/conventions.hpp"
#include "calib/core/imu_error_model.hpp"
#include "db/archive/archive_input.hpp"
#include "db/archive/io_util.hpp"
#include "db/archive/param_json.hpp"
#include "db/archive/run_archive.hpp"

namespace imucal::tools::imucal {

namespace fs = std::filesystem;

namespace {

/// What CALIBRATION held and which parameters were taken from it.
struct LoadedCalibration {
  calib::core::ParamSet params;
  std::string form;     ///< "parameter_set" or "calibrate_json"
  std::string method;   ///< calibrate_json: the method taken
  std::string because;  ///< calibrate_json: why that one
  std::string verdict;  ///< calibrate_json: the run's verdict (PASS or REVIEW), as it said
};

const char* const kMethods[] = {"ains", "nlsq", "legacy"};

/// A calibrate --json method passed when it converged and no limit failed for it.
bool method_passed(const nlohmann::json& j, const std::string& m) {
  const nlohmann::json& r = j.at(m);
  if (!r.is_object() || !r.value("converged", false)) return false;
  if (j.contains("limits") && j["limits"].contains("failures"))
    for (const nlohmann::json& f : j["limits"]["failures"])
      if (f.value("method", "") == m) return false;
  return true;
}

/// The method that holds the run's rests when the calibration said so ("holding", a land run below
/// navigation grade) and it passed: the verdict and the station's active set rest on it. "" else.
std::string holding_method(const nlohmann::json& j) {
  if (!j.contains("holding") || !j["holding"].is_object()) return "";
  const std::string m = j["holding"].value("method", "");
  return j.contains(m) && method_passed(j, m) ? m : "";
}

/// The method to take from a calibrate --json object: --method's, else the one that holds the
/// rests, else the one that passed (AINS first when several did: the station's active set,
/// db/history/SCHEMA.md).
LoadedCalibration from_calibrate_json(const nlohmann::json& j, const std::string& path,
                                      const std::string& method) {
  std::string present;
  for (const char* m : kMethods)
    if (j.contains(m)) present += (present.empty() ? "" : ", ") + std::string(m);
  LoadedCalibration c;
  c.form = "calibrate_json";
  if (!method.empty()) {
    if (!j.contains(method))
      throw std::invalid_argument(path + ": no '" + method + "' result (it holds " + present + ")");
    c.method = method;
    c.because = "chosen with --method";
  } else if (const std::string holding = holding_method(j); !holding.empty()) {
    c.method = holding;
    c.because = "the method that holds the run's rests, the station's active set";
  } else {
    std::vector<std::string> passed;
    for (const char* m : kMethods)
      if (j.contains(m) && method_passed(j, m)) passed.emplace_back(m);
    if (passed.empty())
      throw std::invalid_argument(path + ": no method's result passed its limits (it holds " +
                                  present + "); choose one with --method NAME");
    c.method = passed.front();
    c.because = passed.size() == 1 ? "the method that passed"
                                   : "of the methods that passed, the station's active set";
  }
  if (j.contains("verdict") && j["verdict"].is_string()) c.verdict = j["verdict"];
  const nlohmann::json& r = j.at(c.method);
  if (!r.is_object() || !r.contains("params"))
    throw std::invalid_argument(path + ": field '" + c.method + ".params': missing");
  c.params = db::archive::param_set_from_json(r.at("params"), path + " (" + c.method + ".params)");
  return c;
}

/// CALIBRATION: a parameter-set JSON file or calibrate --json output; anything else is refused
/// naming the file.
LoadedCalibration read_calibration(const std::string& path, const std::string& method) {
  std::error_code ec;
  if (!fs::exists(path, ec))
    throw std::invalid_argument(path +
                                ": no such file (CALIBRATION is a parameter-set JSON or "
                                "what imucal calibrate --json prints)");
  if (fs::is_directory(path, ec))
    throw std::invalid_argument(
        fs::exists(fs::path(path) / "run.toml", ec)
            ? path +
                  ": a run archive holds no calibration result; calibrate it first (imucal "
                  "calibrate " +
                  path + " --json > cal.json) and give that file"
            : path + ": is a directory, not a parameter-set JSON or imucal calibrate --json file");
  const nlohmann::json j = db::archive::parse_json_text(db::archive::read_text_file(path), path);
  if (j.is_object() && j.contains("accel_bias_mps2")) {
    if (!method.empty())
      throw std::invalid_argument(path + ": a parameter set holds one result: --method " + method +
                                  " chooses among imucal calibrate --json's");
    return {db::archive::param_set_from_json(j, path), "parameter_set", "", "", ""};
  }
  if (j.is_object())
    for (const char* m : kMethods)
      if (j.contains(m)) return from_calibrate_json(j, path, method);
  if (j.is_object() && j.contains("error") && j["error"].is_string())
    throw std::invalid_argument(
        path + ": holds an error, not a calibration: " + j["error"].get<std::string>());
  throw std::invalid_argument(
      path +
      ": neither a parameter set (accel_bias_mps2, accel_M, ...) nor imucal calibrate --json "
      "output (ains, nlsq or legacy results)");
}

std::string calibration_text(const CheckArgs& a, const LoadedCalibration& c) {
  if (c.form == "parameter_set") return a.calibration + " (parameter set)";
  return a.calibration + " (imucal calibrate --json, method " + c.method + ": " + c.because +
         (c.verdict.empty() ? "" : "; the calibration's verdict " + c.verdict) + ")";
}

/// DIR's archive with --grade and --min-rest-s applied.
db::archive::RunArchive read_run(const CheckArgs& a) {
  db::archive::RunArchive ar = db::archive::read_archive(a.dir);
  if (!a.grade.empty()) ar.info.grade = *calib::core::parse_grade(a.grade);
  if (a.min_rest_s > 0.0) ar.info.min_rest_s = a.min_rest_s;
  return ar;
}

double mg(double mps2) { return mps2 / kStandardGravity_mps2 * 1e3; }

nlohmann::json check_json(const CheckArgs& a, const LoadedCalibration& c,
                          const db::archive::RunArchive& ar,
                          const calib::core::CalibrationInput& in,
                          const calib::checks::HeldOutCheck& r) {
  nlohmann::json rests = nlohmann::json::array(), moves = nlohmann::json::array();
  for (const auto& x : r.rests)
    rests.push_back({{"t_begin_s", x.t_begin_s},
                     {"t_end_s", x.t_end_s},
                     {"raw_mps2", x.raw_mps2},
                     {"corrected_mps2", x.corrected_mps2}});
  for (const auto& m : r.moves)
    moves.push_back(
        {{"t_from_s", m.t_from_s},
         {"t_to_s", m.t_to_s},
         {"tilt_rad", m.tilt_rad},
         {"raw_rad", m.raw_rad},
         {"corrected_rad", m.corrected_rad},
         {"left_out", m.left_out.empty() ? nlohmann::json(nullptr) : nlohmann::json(m.left_out)}});
  nlohmann::json cal = {{"file", a.calibration}, {"form", c.form}};
  if (!c.method.empty()) cal["method"] = c.method, cal["chosen"] = c.because;
  if (!c.verdict.empty()) cal["verdict"] = c.verdict;
  return {{"calibration", cal},
          {"archive", a.dir},
          {"serial", ar.info.serial},
          {"setting", calib::core::setting_name(in.setting)},
          {"grade", calib::core::grade_name(in.grade)},
          {"samples", in.imu.size()},
          {"gravity_mps2", r.gravity_mps2},
          {"uncalibrated", "nominal values"},
          {"rests", rests},
          {"moves", moves},
          {"rms",
           {{"rest_raw_mps2", r.rest_rms_raw_mps2},
            {"rest_corrected_mps2", r.rest_rms_corrected_mps2},
            {"move_raw_rad", r.move_rms_raw_rad},
            {"move_corrected_rad", r.move_rms_corrected_rad}}},
          {"earth_rate",
           {{"horizontal_removed", r.earth_rate_heading}, {"bound_rad", r.earth_rate_bound_rad}}}};
}

void print_check(const CheckArgs& a, const LoadedCalibration& c, const db::archive::RunArchive& ar,
                 const calib::core::CalibrationInput& in, const calib::checks::HeldOutCheck& r) {
  std::printf("held-out check of %s\non run %s (serial %s, setting %s, grade %s, %zu samples)\n",
              calibration_text(a, c).c_str(), a.dir.c_str(), ar.info.serial.c_str(),
              calib::core::setting_name(in.setting), calib::core::grade_name(in.grade),
              in.imu.size());
  std::printf(
      "local gravity %.5f m/s^2 (%s); uncalibrated: nominal values (nothing subtracted)\n\n",
      r.gravity_mps2, in.site.gravity_mps2 ? "surveyed" : "normal gravity at the site");
  std::printf("%5s %10s %10s %18s %22s\n", "rest", "from [s]", "to [s]", "|f|-g raw [mg]",
              "|f|-g corrected [mg]");
  for (size_t p = 0; p < r.rests.size(); ++p)
    std::printf("%5zu %10.2f %10.2f %18.3f %22.3f\n", p + 1, r.rests[p].t_begin_s,
                r.rests[p].t_end_s, mg(r.rests[p].raw_mps2), mg(r.rests[p].corrected_mps2));
  std::printf("\n%7s %10s %10s %11s %28s %18s\n", "move", "from [s]", "to [s]", "tilt [deg]",
              "gravity carried raw [deg]", "corrected [deg]");
  for (size_t p = 0; p < r.moves.size(); ++p) {
    const auto& m = r.moves[p];
    std::printf("%3zu-%-3zu %10.2f %10.2f %11.1f %28.3f %18.4f%s\n", p + 1, p + 2, m.t_from_s,
                m.t_to_s, m.tilt_rad * kRadToDeg, m.raw_rad * kRadToDeg,
                m.corrected_rad * kRadToDeg, m.left_out.empty() ? "" : "  (not in the RMS)");
  }
  size_t left_out = 0;
  for (size_t p = 0; p < r.moves.size(); ++p)
    if (!r.moves[p].left_out.empty() && ++left_out)
      std::printf("move %zu-%zu not judged: %s\n", p + 1, p + 2, r.moves[p].left_out.c_str());
  std::printf("\nRMS over %zu rests: |f|-g raw %.3f mg, corrected %.3f mg\n", r.rests.size(),
              mg(r.rest_rms_raw_mps2), mg(r.rest_rms_corrected_mps2));
  std::printf("RMS over %zu moves: gravity carried raw %.3f deg, corrected %.4f deg\n",
              r.moves.size() - left_out, r.move_rms_raw_rad * kRadToDeg,
              r.move_rms_corrected_rad * kRadToDeg);
  if (r.earth_rate_heading)
    std::printf("Earth rate: removed (north from each rest's gyros, navigation grade)\n");
  else
    std::printf(
        "Earth rate: its horizontal part is left in (a %s gyro cannot find north): up to %.4f deg "
        "on the longest move\n",
        calib::core::grade_name(in.grade), r.earth_rate_bound_rad * kRadToDeg);
}

}  // namespace

CLI::App* add_check_command(CLI::App& app, CheckArgs& a) {
  auto* c = app.add_subcommand(
      "check",
      "a calibration on another recording of the same unit: per rest |f|-g, per move the gravity "
      "carried by the gyros, uncalibrated beside calibrated");
  c->add_option("calibration", a.calibration,
                "parameter-set JSON, or what imucal calibrate --json printed")
      ->required();
  c->add_option("dir", a.dir, "run archive directory (another recording of the unit)")->required();
  c->add_option("--method", a.method,
                "ains|nlsq|legacy: the result to take from a calibrate --json file (default: the "
                "one that holds the rests, else the one that passed its limits; AINS when several "
                "did)")
      ->check(CLI::IsMember({"ains", "nlsq", "legacy"}));
  c->add_option("--grade", a.grade,
                "navigation|tactical|mems: the unit's grade instead of run.toml's [prior] grade "
                "(the rest detector; whether the gyros find north)")
      ->check(CLI::IsMember({"navigation", "tactical", "mems"}));
  c->add_option("--min-rest-s", a.min_rest_s,
                "field runs: the shortest rest kept, s (default: the detector's)")
      ->check(CLI::Range(0.5, 600.0));
  c->add_flag("--json", a.json, "print one JSON object (SI units)");
  return c;
}

CLI::App* add_apply_command(CLI::App& app, CheckArgs& a) {
  auto* c = app.add_subcommand("apply",
                               "write a run archive with the IMU data corrected by a calibration");
  c->add_option("calibration", a.calibration,
                "parameter-set JSON, or what imucal calibrate --json printed")
      ->required();
  c->add_option("dir", a.dir, "run archive directory to correct")->required();
  c->add_option("--out", a.out_dir, "the corrected archive's directory (must not exist)")
      ->required();
  c->add_option("--method", a.method,
                "ains|nlsq|legacy: the result to take from a calibrate --json file (default: the "
                "one that holds the rests, else the one that passed its limits; AINS when several "
                "did)")
      ->check(CLI::IsMember({"ains", "nlsq", "legacy"}));
  c->add_flag("--json", a.json, "print one JSON object");
  return c;
}

int cmd_check(const CheckArgs& a) {
  const LoadedCalibration cal = read_calibration(a.calibration, a.method);
  db::archive::RunArchive ar = read_run(a);
  if (ar.info.setting == calib::core::Setting::kSea)
    throw std::invalid_argument(a.dir +
                                ": a sea run has no still rest (the deck rocks and heaves); the "
                                "held-out check needs a land or table run");
  const calib::core::CalibrationInput in = db::archive::to_calibration_input(ar);
  calib::checks::HeldOutCheck r;
  try {
    r = calib::checks::check_held_out(in, cal.params);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(a.dir + ": " + e.what());
  }
  if (a.json)
    std::cout << check_json(a, cal, ar, in, r).dump(2) << '\n';
  else
    print_check(a, cal, ar, in, r);
  return 0;
}

int cmd_apply(const CheckArgs& a) {
  std::error_code ec;
  if (fs::exists(a.out_dir, ec) || fs::is_symlink(a.out_dir, ec))
    throw std::invalid_argument(
        "--out " + a.out_dir +
        ": already exists; apply writes a new archive (remove it or choose another --out)");
  const LoadedCalibration cal = read_calibration(a.calibration, a.method);
  db::archive::RunArchive ar = db::archive::read_archive(a.dir);
  if (ar.imu.empty()) throw std::invalid_argument(a.dir + "/imu.csv: no IMU samples to correct");
  const calib::core::ImuCompensator comp(cal.params);
  for (calib::core::ImuIncrement& s : ar.imu) {
    s.dtheta_rad = comp.dtheta(s.dtheta_rad, s.dt_s);
    s.dv_mps = comp.dv(s.dv_mps, s.dt_s);
  }
  const bool had_truth = ar.truth.has_value();
  ar.truth.reset();  // the injected parameters describe the uncorrected unit
  db::archive::write_archive(a.out_dir, ar);  // a sibling temporary directory renamed into place
  if (a.json) {
    nlohmann::json j = {{"archive", a.out_dir},
                        {"from", a.dir},
                        {"calibration", {{"file", a.calibration}, {"form", cal.form}}},
                        {"samples", ar.imu.size()},
                        {"truth_dropped", had_truth}};
    if (!cal.method.empty()) j["calibration"]["method"] = cal.method;
    std::cout << j.dump(2) << '\n';
  } else {
    std::printf("wrote %s: %zu samples of %s corrected with %s%s\n", a.out_dir.c_str(),
                ar.imu.size(), a.dir.c_str(), calibration_text(a, cal).c_str(),
                had_truth ? "; truth.json not carried (it describes the uncorrected unit)" : "");
  }
  return 0;
}

}  // namespace imucal::tools::imucal
