#include "calib/checks/held_out_check.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "calib/core/earth.hpp"
#include "calib/core/imu_error_model.hpp"
#include "calib/core/readable_number.hpp"
#include "calib/core/rotation.hpp"

namespace imucal::calib::checks {

namespace {

using Eigen::Matrix3d;
using Eigen::Vector3d;

/// The compensated mean specific force and rate over one rest.
struct RestMeans {
  Vector3d f_mps2 = Vector3d::Zero(), w_radps = Vector3d::Zero();
};

RestMeans rest_means(const ImuSeries& imu, const TrimmedRest& r, const ImuCompensator& comp) {
  RestMeans m;
  double T = 0.0;
  for (size_t k = r.begin; k < r.end; ++k) {
    m.f_mps2 += comp.dv(imu[k].dv_mps, imu[k].dt_s);
    m.w_radps += comp.dtheta(imu[k].dtheta_rad, imu[k].dt_s);
    T += imu[k].dt_s;
  }
  m.f_mps2 /= T;
  m.w_radps /= T;
  return m;
}

/// The Earth rate in body axes at a rest whose gravity direction is `down`: its vertical part
/// −Ω sin φ · down always; its horizontal part Ω cos φ towards north only where north is known
/// from the rest's mean rate (gyrocompassing, navigation grade). NED: ω_ie = (Ω cos φ, 0, −Ω sin
/// φ).
Vector3d earth_rate_b(const Vector3d& down, const Vector3d& w_mean, double lat_rad,
                      bool north_known) {
  const double om = wgs84::kEarthRate_radps;
  Vector3d w = -om * std::sin(lat_rad) * down;
  const Vector3d horizontal = w_mean - w_mean.dot(down) * down;
  if (north_known && horizontal.norm() > 0.0) w += om * std::cos(lat_rad) * horizontal.normalized();
  return w;
}

/// C_{b(k0)←b(k1)} with respect to inertial space: the compensated gyros integrated over
/// samples k0+1 .. k1, as the legacy method's joint model integrates them.
Matrix3d gyro_rotation(const ImuSeries& imu, const ImuCompensator& comp, size_t k0, size_t k1) {
  Matrix3d C = Matrix3d::Identity();
  for (size_t k = k0 + 1; k <= k1; ++k)
    C = C * rotvec_to_matrix<double>(comp.dtheta(imu[k].dtheta_rad, imu[k].dt_s));
  return C;
}

double angle_between(const Vector3d& a, const Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b));
}

/// One column of the table: the run compensated with `params` (zero: the raw data).
struct HeldOutColumn {
  std::vector<double> magnitude_mps2;  ///< |mean f| − g per rest
  std::vector<Vector3d> down;          ///< gravity direction per rest, body
  std::vector<double> carried_rad;     ///< per move: carried against seen
};

HeldOutColumn column(const CalibrationInput& in, const std::vector<TrimmedRest>& rests,
                     const ParamSet& params, double g, bool north_known) {
  const ImuCompensator comp(params);
  HeldOutColumn c;
  std::vector<Vector3d> w_ie_b;
  for (const TrimmedRest& r : rests) {
    const RestMeans m = rest_means(in.imu, r, comp);
    c.magnitude_mps2.push_back(m.f_mps2.norm() - g);
    c.down.push_back(-m.f_mps2.normalized());
    w_ie_b.push_back(earth_rate_b(c.down.back(), m.w_radps, in.site.lat_rad, north_known));
  }
  for (size_t p = 0; p + 1 < rests.size(); ++p) {
    const size_t k0 = rests[p].mid, k1 = rests[p + 1].mid;
    const double dt_s = in.imu[k1].t_s - in.imu[k0].t_s;
    // Gravity is fixed to the Earth, which turns under it by ω_ie·Δt in inertial space.
    const Matrix3d R = gyro_rotation(in.imu, comp, k0, k1).transpose() *
                       rotvec_to_matrix<double>(Vector3d(w_ie_b[p] * dt_s));
    c.carried_rad.push_back(angle_between(R * c.down[p], c.down[p + 1]));
  }
  return c;
}

double rms(const std::vector<double>& v) {
  double s = 0.0;
  for (double x : v) s += x * x;
  return v.empty() ? 0.0 : std::sqrt(s / static_cast<double>(v.size()));
}

/// The two columns side by side, with the spans they were taken over.
HeldOutCheck assemble(const CalibrationInput& in, const std::vector<TrimmedRest>& rests,
                      const HeldOutColumn& raw, const HeldOutColumn& cor) {
  HeldOutCheck out;
  for (size_t p = 0; p < rests.size(); ++p)
    out.rests.push_back({in.imu[rests[p].begin].t_s - in.imu[rests[p].begin].dt_s,
                         in.imu[rests[p].end - 1].t_s, raw.magnitude_mps2[p],
                         cor.magnitude_mps2[p]});
  std::vector<double> judged_raw, judged_cor;
  for (size_t p = 0; p + 1 < rests.size(); ++p) {
    const std::string spoilt =
        reasons_text(spans_within(in.unusable, rests[p].mid, rests[p + 1].mid + 1));
    out.moves.push_back({in.imu[rests[p].mid].t_s, in.imu[rests[p + 1].mid].t_s,
                         angle_between(cor.down[p], cor.down[p + 1]), raw.carried_rad[p],
                         cor.carried_rad[p], spoilt});
    if (!spoilt.empty()) continue;
    judged_raw.push_back(raw.carried_rad[p]);
    judged_cor.push_back(cor.carried_rad[p]);
  }
  out.rest_rms_raw_mps2 = rms(raw.magnitude_mps2);
  out.rest_rms_corrected_mps2 = rms(cor.magnitude_mps2);
  out.move_rms_raw_rad = rms(judged_raw);
  out.move_rms_corrected_rad = rms(judged_cor);
  return out;
}

}  // namespace

HeldOutCheck check_held_out(const CalibrationInput& in, const ParamSet& params,
                            const HeldOutCheckOptions& options) {
  check_input_samples(in, "held-out check: ");
  const std::vector<TrimmedRest> rests =
      trimmed_rests(in, options.min_rest_samples, options.trim_s);
  if (rests.size() < 2)
    throw std::invalid_argument(
        "held-out check: found " + std::to_string(rests.size()) + " usable rest" +
        (rests.size() == 1 ? "" : "s") + " (at least " + std::to_string(options.min_rest_samples) +
        " samples still, " + seconds_text(options.trim_s) +
        " trimmed at both ends); checking a calibration needs at least 2: a rest before and "
        "after a move");
  const double g = EarthModel(in.site).gravity_mps2();
  // Below navigation grade a gyro cannot find north (header comment): the Earth rate's
  // horizontal part stays in the moves' figures, bounded here by the longest move.
  const bool north_known = in.grade == Grade::kNavigation;
  HeldOutCheck out = assemble(in, rests, column(in, rests, ParamSet{}, g, north_known),
                              column(in, rests, params, g, north_known));
  out.gravity_mps2 = g;
  out.earth_rate_heading = north_known;
  if (!north_known)
    for (const MoveFigure& m : out.moves)
      out.earth_rate_bound_rad =
          std::max(out.earth_rate_bound_rad,
                   wgs84::kEarthRate_radps * std::cos(in.site.lat_rad) * (m.t_to_s - m.t_from_s));
  return out;
}

}  // namespace imucal::calib::checks
