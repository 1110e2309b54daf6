#include "calib/checks/data_check.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "calib/core/conventions.hpp"
#include "calib/core/earth.hpp"
#include "calib/core/rotation.hpp"

namespace imucal::calib::checks {
using namespace calib::core;

namespace {

using Eigen::Matrix3d;
using Eigen::Vector3d;

const char* const kChannel[6] = {"gyro x", "gyro y", "gyro z", "accel x", "accel y", "accel z"};

double channel(const ImuIncrement& s, int c) { return c < 3 ? s.dtheta_rad(c) : s.dv_mps(c - 3); }

template <class... Args>
std::string fmt(const char* f, Args... args) {
  char buf[320];
  std::snprintf(buf, sizeof buf, f, args...);
  return buf;
}

double angle_deg(const Vector3d& a, const Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b)) / kDegToRad;
}

/// The longest stretch of identical consecutive values of one channel.
void check_stuck(const ImuSeries& imu, const DataCheckOptions& o, std::vector<DataProblem>& out) {
  for (int c = 0; c < 6; ++c) {
    size_t best = 0, run = 1, best_end = 0;
    for (size_t i = 1; i < imu.size(); ++i) {
      run = channel(imu[i], c) == channel(imu[i - 1], c) ? run + 1 : 1;
      if (run > best) {
        best = run;
        best_end = i;
      }
    }
    if (imu.size() < 2 || static_cast<double>(best) < o.stuck_fraction * imu.size()) continue;
    const ImuIncrement& s = imu[best_end];
    out.push_back({"stuck channel",
                   std::string(kChannel[c]) +
                       fmt(" holds %.6g for %zu of %zu samples from t = %.2f s: a stuck or dead "
                           "sensor axis",
                           channel(s, c), best, imu.size(), imu[best_end + 1 - best].t_s)});
  }
}

/// A clipped channel: its largest magnitude, reached exactly, many times — and in stretches of
/// consecutive samples (a clipped rotation stays clipped), which noise that happens to repeat its
/// largest value never does.
void check_saturation(const ImuSeries& imu, const DataCheckOptions& o,
                      std::vector<DataProblem>& out) {
  for (int c = 0; c < 6; ++c) {
    double peak = 0.0;
    for (const auto& s : imu) peak = std::max(peak, std::abs(channel(s, c)));
    if (!(peak > 0.0)) continue;
    int hits = 0, run = 0, longest = 0;
    double first_t = 0.0;
    for (const auto& s : imu) {
      if (std::abs(channel(s, c)) != peak) {
        run = 0;
        continue;
      }
      if (hits++ == 0) first_t = s.t_s;
      longest = std::max(longest, ++run);
    }
    if (hits < o.saturation_repeats || longest < 3) continue;
    const double dt = imu.size() > 1 ? imu[1].t_s - imu[0].t_s : 0.01;
    const bool gyro = c < 3;
    out.push_back({"saturation", std::string(kChannel[c]) +
                                     fmt(" clipped: %d samples at ±%.6g (%.4g %s), first at t = "
                                         "%.2f s: the sensor's range was exceeded",
                                         hits, peak, gyro ? peak / dt / kDegToRad : peak / dt,
                                         gyro ? "deg/s" : "m/s²", first_t)});
  }
}

/// The IMU's clock: every step between consecutive samples within 50 % of the median step (a
/// jump forward or back, or a stretch of lost samples the capture did not fill, shifts every
/// later sample against the motion).
void check_clock(const ImuSeries& imu, std::vector<DataProblem>& out) {
  std::vector<double> steps;
  steps.reserve(imu.size());
  for (size_t i = 1; i < imu.size(); ++i) steps.push_back(imu[i].t_s - imu[i - 1].t_s);
  std::vector<double> sorted = steps;
  std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
  const double median = sorted[sorted.size() / 2];
  size_t bad = 0, first = 0;
  for (size_t i = 0; i < steps.size(); ++i)
    if (!(std::abs(steps[i] - median) <= 0.5 * median) && bad++ == 0) first = i;
  if (bad == 0) return;
  out.push_back({"clock jump", fmt("the IMU's time steps by %.6g s after t = %.3f s (sample "
                                   "interval %.6g s; %zu such step(s)): a clock jump or a gap in "
                                   "the stream",
                                   steps[first], imu[first].t_s, median, bad)});
}

/// Mean specific force of each rest period, body frame.
std::vector<Vector3d> rest_means(const CalibrationInput& in, const std::vector<RestPeriod>& rests) {
  std::vector<Vector3d> f;
  for (const auto& r : rests) {
    Vector3d dv = Vector3d::Zero();
    double t = 0.0;
    for (size_t i = r.begin; i < r.end; ++i) {
      dv += in.imu[i].dv_mps;
      t += in.imu[i].dt_s;
    }
    f.push_back(t > 0 ? Vector3d(dv / t) : Vector3d::Zero());
  }
  return f;
}

/// The rest means with each accelerometer's offset and scale removed by an ellipsoid fit
/// (|diag(1 + s)(f_p - b)| = g at every rest, Gauss–Newton from b = 0, s = 0). A MEMS unit's
/// 200 mg biases and 10 % scales tilt where gravity is seen by up to 20° and turn it by
/// different amounts at each rest; a swap or a sign flip survives the fit (it leaves every
/// magnitude alone), so the gyro-vs-gravity check still sees it. The raw means when the rests
/// cannot fix six unknowns or the fit lands outside any plausible unit (a dead axis).
std::vector<Vector3d> without_accel_offset(const std::vector<Vector3d>& f, double g) {
  if (f.size() < 9) return f;
  Eigen::Matrix<double, 6, 1> x = Eigen::Matrix<double, 6, 1>::Zero();  // (b, s)
  for (int it = 0; it < 30; ++it) {
    Eigen::MatrixXd J(static_cast<Eigen::Index>(f.size()), 6);
    Eigen::VectorXd r(static_cast<Eigen::Index>(f.size()));
    for (size_t p = 0; p < f.size(); ++p) {
      const Vector3d u = f[p] - x.head<3>();
      const Vector3d y = (Vector3d::Ones() + x.tail<3>()).cwiseProduct(u);
      const double rho = std::max(y.norm(), 1e-9);
      const auto i = static_cast<Eigen::Index>(p);
      r(i) = rho - g;
      J.block<1, 3>(i, 0) = -(y / rho).cwiseProduct(Vector3d::Ones() + x.tail<3>()).transpose();
      J.block<1, 3>(i, 3) = (y / rho).cwiseProduct(u).transpose();
    }
    const Eigen::Matrix<double, 6, 1> dx = (J.transpose() * J).ldlt().solve(-J.transpose() * r);
    if (!dx.allFinite()) return f;
    x += dx;
    if (dx.norm() < 1e-10 * (1.0 + x.norm())) break;
  }
  if (!x.allFinite() || x.head<3>().norm() > 0.5 * g || x.tail<3>().cwiseAbs().maxCoeff() > 0.5)
    return f;
  std::vector<Vector3d> out;
  for (const Vector3d& fp : f)
    out.push_back((Vector3d::Ones() + x.tail<3>()).cwiseProduct(fp - x.head<3>()));
  return out;
}

/// The IMU's own rotation from sample a to sample b: body at b relative to body at a.
Matrix3d integrate(const ImuSeries& imu, size_t a, size_t b, const Vector3d& offset_radps) {
  Matrix3d C = Matrix3d::Identity();
  for (size_t i = a; i < b; ++i)
    C = C * rotvec_to_matrix<double>(Vector3d(imu[i].dtheta_rad - offset_radps * imu[i].dt_s));
  return C;
}

/// `f`: the rests' raw mean specific force (the magnitudes); `f_dir`: the same with each
/// accelerometer's offset and scale removed when the grade asks for it (the directions).
void check_gravity(const CalibrationInput& in, const std::vector<RestPeriod>& rests,
                   const std::vector<Vector3d>& f, const std::vector<Vector3d>& f_dir,
                   const DataCheckOptions& o, std::vector<DataProblem>& out) {
  const double g = EarthModel(in.site).gravity_mps2();
  size_t worst = 0;
  double worst_rel = 0.0;
  for (size_t k = 0; k < f.size(); ++k) {
    const double rel = std::abs(f[k].norm() - g) / g;
    if (rel > worst_rel) {
      worst_rel = rel;
      worst = k;
    }
  }
  if (worst_rel > o.gravity_magnitude_tol)
    out.push_back({"gravity magnitude",
                   fmt("the accelerometers measure |f| = %.4f m/s² at rest %zu (t = %.1f s), "
                       "local gravity is %.4f m/s²: an accelerometer axis dead, stuck or far "
                       "outside its scale",
                       f[worst].norm(), worst + 1, in.imu[rests[worst].begin].t_s, g)});
  if (!in.has_reference_attitude()) return;
  // Where the table puts gravity: f_b = C_bnᵀ (0, 0, -g) at rest (NED, down positive).
  std::vector<double> off;
  for (size_t k = 0; k < f.size(); ++k) {
    const size_t mid = (rests[k].begin + rests[k].end) / 2;
    const Vector3d expected = in.reference[mid].C_bn_ref.transpose() * Vector3d(0, 0, -g);
    off.push_back(angle_deg(f_dir[k], expected));
  }
  // Calibration errors never move gravity by degrees at any rest: two such rests are a finding
  // (an axis swapped or flipped shows only in the rests where it is not horizontal).
  const size_t bad = static_cast<size_t>(
      std::count_if(off.begin(), off.end(), [&](double d) { return d > o.direction_tol_deg; }));
  const size_t worst_k =
      static_cast<size_t>(std::max_element(off.begin(), off.end()) - off.begin());
  if (bad >= 2)
    out.push_back({"gravity direction",
                   fmt("gravity at rest is up to %.1f° (rest %zu; %zu of %zu rests beyond %.0f°) "
                       "from where the table's attitude puts it: the unit is mounted in a wrong "
                       "fixture orientation, or accelerometer axes are swapped or sign-flipped",
                       off[worst_k], worst_k + 1, bad, off.size(), o.direction_tol_deg)});
}

void check_rotations(const CalibrationInput& in, const std::vector<RestPeriod>& rests,
                     const std::vector<Vector3d>& f, const DataCheckOptions& o,
                     std::vector<DataProblem>& out) {
  double worst_carry = 0.0, worst_table = 0.0;
  size_t worst_carry_k = 0, worst_table_k = 0;
  double table_angle_at_worst = 0.0, imu_angle_at_worst = 0.0, mismatch_at_worst = 0.0;
  const Vector3d offset =
      o.remove_gyro_offset ? median_rest_rate_radps(in.imu, rests) : Vector3d::Zero();
  for (size_t k = 0; k + 1 < rests.size(); ++k) {
    const size_t a = (rests[k].begin + rests[k].end) / 2,
                 b = (rests[k + 1].begin + rests[k + 1].end) / 2;
    // A clipped or dropped sample spoils this move alone: the methods leave it out.
    if (!spans_within(in.unusable, a, b + 1).empty()) continue;
    const Matrix3d C_imu = integrate(in.imu, a + 1, b + 1, offset);  // body at b w.r.t. at a
    // Gravity seen at rest k, carried by the gyros to rest k+1 (Earth rate ≪ the tolerance).
    // Beyond what a scale factor within a few per cent could do over this rotation.
    // The angle turned along the path, not the net rotation (a turn past 180° nets less).
    double turned_deg = 0.0;
    for (size_t i = a + 1; i < b + 1; ++i)
      turned_deg += (in.imu[i].dtheta_rad - offset * in.imu[i].dt_s).norm() / kDegToRad;
    const double carry =
        angle_deg(C_imu.transpose() * f[k], f[k + 1]) - o.rotation_tol_fraction * turned_deg;
    if (carry > worst_carry) {
      worst_carry = carry;
      worst_carry_k = k;
    }
    if (!in.has_reference_attitude()) continue;
    const Matrix3d C_table = in.reference[a].C_bn_ref.transpose() * in.reference[b].C_bn_ref;
    const double table_deg = matrix_to_rotvec(C_table).norm() / kDegToRad;
    const double mismatch = matrix_to_rotvec(C_table.transpose() * C_imu).norm() / kDegToRad;
    const double tol = o.rotation_tol_deg + o.rotation_tol_fraction * table_deg;
    if (mismatch - tol > worst_table) {
      worst_table = mismatch - tol;
      worst_table_k = k;
      table_angle_at_worst = table_deg;
      imu_angle_at_worst = matrix_to_rotvec(C_imu).norm() / kDegToRad;
      mismatch_at_worst = mismatch;
    }
  }
  if (worst_table > 0.0)
    out.push_back({"table vs IMU rotation",
                   fmt("between rests %zu and %zu the table turned %.1f°, the IMU %.1f°, the "
                       "two rotations %.1f° apart: ",
                       worst_table_k + 1, worst_table_k + 2, table_angle_at_worst,
                       imu_angle_at_worst, mismatch_at_worst) +
                       (imu_angle_at_worst < 0.1 * table_angle_at_worst
                            ? "the unit did not move with the table (loose, or not on it)"
                            : "gyro axes swapped or sign-flipped, or a gyro dead")});
  if (worst_carry > o.direction_tol_deg)
    out.push_back({"gyro vs gravity",
                   fmt("the gyros' rotation between rests %zu and %zu carries gravity %.1f° "
                       "(beyond a few per cent of scale) away from where the accelerometers see "
                       "it: gyro or accelerometer axes "
                       "swapped or sign-flipped, or a sensor dead",
                       worst_carry_k + 1, worst_carry_k + 2, worst_carry)});
}

}  // namespace

DataCheckOptions data_check_options(const UnitPrior& prior) {
  DataCheckOptions o;
  if (prior.plain_navigation()) return o;
  const GradePrior p = prior.envelope();
  // |f| at rest: each axis' scale and bias (at 2 g of bias for margin, √3 axes at worst).
  o.gravity_magnitude_tol =
      std::max(o.gravity_magnitude_tol, p.scale + 2.0 * std::sqrt(3.0) * p.accel_bias_mps2 / 9.8);
  // Gravity carried across a move: the gyros' scale and misalignment turn it by that fraction of
  // the angle, the accelerometers' misalignment moves where it is seen at each end.
  o.rotation_tol_fraction = std::max(o.rotation_tol_fraction, p.scale + 2.0 * p.misalignment_rad);
  o.direction_tol_deg = std::max(o.direction_tol_deg, 3.0 + 2.0 * p.misalignment_rad / kDegToRad);
  o.remove_gyro_offset = true;
  o.remove_accel_offset = true;
  return o;
}

std::vector<DataProblem> check_data(const CalibrationInput& in, const DataCheckOptions& o) {
  std::vector<DataProblem> out;
  if (in.imu.size() < 2 || in.reference.size() != in.imu.size()) return out;
  // A field recording's clipped and dropped samples are judged where they are (in.unusable: the
  // move that holds one is left out); a table run is captured by the station, which runs it again.
  if (in.has_reference_attitude()) check_clock(in.imu, out);
  check_stuck(in.imu, o, out);
  if (in.has_reference_attitude()) check_saturation(in.imu, o, out);
  const std::vector<RestPeriod> rests = find_rest_periods(in, o.min_rest_samples);
  if (rests.empty()) return out;
  const std::vector<Vector3d> f = rest_means(in, rests);
  // Below navigation grade each accelerometer's offset and scale (up to 200 mg and 30 %) would
  // tilt gravity by up to 20°: the directions are compared with them removed (an ellipsoid fit to
  // |f| = g), which leaves a swap or a sign flip as it is.
  const std::vector<Vector3d> f_dir =
      o.remove_accel_offset ? without_accel_offset(f, EarthModel(in.site).gravity_mps2()) : f;
  check_gravity(in, rests, f, f_dir, o, out);
  check_rotations(in, rests, f_dir, o, out);
  return out;
}

DataCheckError::DataCheckError(std::vector<DataProblem> problems)
    : std::invalid_argument([&] {
        std::string m = "the IMU data fail the sanity checks (not a calibration matter):";
        for (const auto& p : problems) m += " [" + p.symptom + "] " + p.detail + ";";
        m.pop_back();
        return m;
      }()),
      problems_(std::move(problems)) {}

}  // namespace imucal::calib::checks
