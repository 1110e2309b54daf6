#include "calib/sim/truth_stream.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

#include "calib/sim/truth_physics.hpp"

namespace imucal::calib::sim {
using namespace calib::core;
using namespace calib::effects;

TruthStream::TruthStream(const TableGeometry& geometry, const Site& site, const UnitModel& unit,
                         const SimOptions& options)
    : dt_s_(1.0 / options.rate_hz) {
  if (!(std::isfinite(options.rate_hz) && options.rate_hz > 0.0))
    throw std::invalid_argument("TruthStream: rate_hz must be positive and finite, got " +
                                std::to_string(options.rate_hz));
  // A hand's motion fades out before its rest ends (calib/effects/rest_tremor.hpp): a stream does
  // not know when the table will move next.
  if (unit.effects.active(EffectId::kRestTremor))
    throw std::invalid_argument(
        "TruthStream: effect rest_tremor (a hand holding the unit in its rests) needs each rest's "
        "end in advance, which a stream does not know: simulate the run with the batch simulator");
  kin_ = std::make_unique<TruthKinematics>(geometry, site, unit, dt_s_);
  sensor_ = std::make_unique<TruthSensor>(unit, dt_s_, options.seed, options.noise);
}

TruthStream::~TruthStream() = default;
TruthStream::TruthStream(TruthStream&&) noexcept = default;
TruthStream& TruthStream::operator=(TruthStream&&) noexcept = default;

// Same arithmetic as simulate(): sample k covers [k dt, (k + 1) dt].
double TruthStream::next_time_s() const { return static_cast<double>(k_ + 1) * dt_s_; }
double TruthStream::interval_start_s() const { return static_cast<double>(k_) * dt_s_; }
bool TruthStream::needs_interior_states() const { return kin_->size_effect(); }

ImuIncrement TruthStream::next(const StateAt& state_at, const std::vector<double>& accel_breaks_s) {
  const double t0 = interval_start_s();
  const double t1 = next_time_s();
  if (!have_prev_) {
    C_prev_ = kin_->C_bn(state_at(t0));
    have_prev_ = true;
  }
  Eigen::Vector3d dv = kin_->dv_gravity(C_prev_);
  if (kin_->size_effect()) {
    std::vector<double> edges{t0};
    for (double b : accel_breaks_s) {
      if (!(b > edges.back() && b < t1))
        throw std::invalid_argument("TruthStream::next: acceleration breakpoint " +
                                    std::to_string(b) +
                                    " s is not ascending inside the interval (" +
                                    std::to_string(t0) + ", " + std::to_string(t1) + ") s");
      edges.push_back(b);
    }
    edges.push_back(t1);
    dv += kin_->dv_lever(C_prev_, edges, state_at);
  }
  // The end state last: the quadrature nodes above lie before it (forward-only callers).
  const Eigen::Matrix3d C_cur = kin_->C_bn(state_at(t1));
  const Eigen::Vector3d dtheta = kin_->dtheta(C_prev_, C_cur);

  ImuIncrement s;
  s.t_s = t1;
  s.dt_s = dt_s_;
  sensor_->measure(dtheta, dv, t0, s);
  s.temp_c = 25.0;
  C_prev_ = C_cur;
  ++k_;
  return s;
}

void TruthStream::reseed_noise(uint64_t seed) { sensor_->reseed_noise(seed); }

}  // namespace imucal::calib::sim
