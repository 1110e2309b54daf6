#include "calib/checks/crlb.hpp"

#include <cmath>
#include <stdexcept>

#include "calib/ains/ains_filter.hpp"
#include "calib/core/calibration_input.hpp"
#include "calib/core/rotation.hpp"
#include "calib/core/strapdown.hpp"

namespace imucal::calib::checks {
using namespace calib::ains;
using namespace calib::core;

using Eigen::Matrix3d;
using Eigen::Vector3d;

namespace {

/// Rest intervals of the profile (consecutive rest segments merged), shrunk by the simulator's
/// rest guard so the aiding epochs match those of a simulated or recorded run.
std::vector<std::pair<double, double>> rest_intervals(const sequences::MotionProfile& profile,
                                                      double guard_s) {
  std::vector<std::pair<double, double>> out;
  for (const auto& seg : profile.segments) {
    if (seg.kind != sequences::SegmentKind::kRest) continue;
    if (!out.empty() && std::abs(out.back().second - seg.t0_s) < 1e-9)
      out.back().second = seg.t1_s;
    else
      out.emplace_back(seg.t0_s, seg.t1_s);
  }
  for (auto& r : out) {
    r.first += guard_s;
    r.second -= guard_s;
  }
  return out;
}

}  // namespace

CrlbResult compute_crlb(const sequences::MotionProfile& profile, const TableGeometry& geometry,
                        const Site& site, const NoiseModel& noise, double rate_hz,
                        const AinsOptions& opt) {
  if (profile.segments.empty() || !(profile.duration_s() > 0.0))
    throw std::invalid_argument("compute_crlb: motion profile '" + profile.name + "' is empty");
  if (!(std::isfinite(rate_hz) && rate_hz > 0.0))
    throw std::invalid_argument("compute_crlb: rate_hz must be finite and > 0");

  // Noise-free increments of the true trajectory (the covariance depends on the trajectory only;
  // the small quadrature error of these increments is absorbed by the aiding like real noise).
  const TableModel table(geometry);
  const EarthModel earth(site);
  const Strapdown ins(earth);
  const Vector3d g_n(0.0, 0.0, ins.gravity_at(site.lat_rad, site.height_m));
  const Vector3d w_ie_n = earth.w_ie_n();
  const double dt = 1.0 / rate_hz;
  const size_t n = static_cast<size_t>(std::floor(profile.duration_s() * rate_hz + 1e-9)) + 1;
  const Matrix3d C_earth = rotvec_to_matrix<double>(Vector3d(w_ie_n * dt));
  const auto rests = rest_intervals(profile, kTableRestGuard_s);

  CalibrationInput in;
  in.site = site;
  in.noise = noise;
  in.imu.resize(n);
  in.reference.resize(n);
  size_t r = 0;
  Matrix3d C_prev = Matrix3d::Identity();
  Vector3d f_prev = Vector3d::Zero();
  for (size_t k = 0; k < n; ++k) {
    const double t = static_cast<double>(k) * dt;
    const sequences::TableState st = profile.at(t);
    const Matrix3d C = table.C_bn(st.outer_rad, st.inner_rad);
    const Vector3d f_b = -C.transpose() * g_n;
    ImuIncrement& s = in.imu[k];
    s.t_s = t;
    s.dt_s = dt;
    if (k > 0) {
      // exp([dθ x]) = C_bn(k-1)^T exp([ω_ie dt x]) C_bn(k)  (inverse of the strapdown step)
      s.dtheta_rad = matrix_to_rotvec(C_prev.transpose() * C_earth * C);
      s.dv_mps = 0.5 * dt * (f_prev + rotvec_to_matrix<double>(s.dtheta_rad) * f_b);
    } else {
      s.dv_mps = f_b * dt;
    }
    while (r < rests.size() && rests[r].second < t) ++r;
    in.reference[k].t_s = t;
    in.reference[k].C_bn_ref = C;
    in.reference[k].at_rest = r < rests.size() && t >= rests[r].first && t <= rests[r].second;
    C_prev = C;
    f_prev = f_b;
  }

  ains::PreparedInput pin;
  try {
    pin = ains::prepare_input(in, opt);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument("compute_crlb: profile '" + profile.name + "': " + e.what());
  }
  ains::PassConfig cfg;
  cfg.prior_sigma = effective_prior_sigma(opt);
  cfg.nominal = ParamSet{};
  const ains::PassResult pass = ains::run_pass(pin, opt, cfg, nullptr);
  CrlbResult out;
  out.cov = ains::sensor_cov_to_params(pass.P);
  out.sigma = sigma_from_covariance(out.cov);
  return out;
}

ParamVector crlb_prior_ratio(const CrlbResult& crlb, const AinsOptions& opt) {
  const ParamVector prior = effective_prior_sigma(opt).to_vector();
  return crlb.sigma.to_vector().cwiseQuotient(prior);
}

std::vector<std::string> unobservable_parameters(const CrlbResult& crlb, const AinsOptions& opt) {
  const ParamVector ratio = crlb_prior_ratio(crlb, opt);
  std::vector<std::string> out;
  for (int i = 0; i < ParamSet::kSize; ++i) {
    const bool heading = i == ParamSet::kSize - 1;  // table_misalignment_rad[2]
    const double limit = heading ? kUnobservableSigmaRatioTableHeading : kUnobservableSigmaRatio;
    if (!(ratio(i) <= limit)) out.push_back(param_info(i).name);
  }
  return out;
}

}  // namespace imucal::calib::checks
