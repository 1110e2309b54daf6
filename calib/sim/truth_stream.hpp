#pragma once
// Streaming truth simulator: the increments of calib::sim::simulate() (truth_sim.hpp) for a table
// whose motion is only known as it happens — a simulated PLC can only step forward in time. The
// caller hands next() a function giving the table state at a time; it is called with non-decreasing
// times inside [t_{k-1}, t_k]: the interval start (first sample only), the Gauss-Legendre nodes
// (size effect only) and the interval end. Same physics as the batch form (truth_physics.hpp):
// exact dθ from the endpoint attitudes, dv by quadrature, then the error model, effects, noise and
// quantisation. With the same options and seed, driving the stream with a MotionProfile's at()
// reproduces simulate().
//
// Effects: the sensor-level effects stream as they are; the size effect (lever arms) needs the
// times where the table's angular acceleration jumps inside an interval (give them to next(), or
// the quadrature is not exact across them); the table-time-offset effect acts on the encoder log,
// which a stream does not produce: the caller that reports encoder angles (the station simulator's
// PLC) must report the angles of t - offset (calib/effects/table_time_offset.hpp). rest_tremor (a
// hand's motion, faded out before each rest's end) is refused: a stream does not know that end.
#include <cstdint>
#include <functional>
#include <memory>
#include <vector>

#include "calib/core/imu_increment.hpp"
#include "calib/core/table_model.hpp"
#include "calib/sim/truth_sim.hpp"
#include "sequences/motion_profile.hpp"

namespace imucal::calib::sim {
using namespace calib::core;
using namespace calib::effects;

class TruthKinematics;
class TruthSensor;

class TruthStream {
 public:
  using StateAt = std::function<sequences::TableState(double t_s)>;

  /// Throws std::invalid_argument for a non-positive or non-finite rate, or rest_tremor.
  TruthStream(const TableGeometry& geometry, const Site& site, const UnitModel& unit,
              const SimOptions& options);
  ~TruthStream();
  TruthStream(TruthStream&&) noexcept;
  TruthStream& operator=(TruthStream&&) noexcept;

  /// The next sample: increments over [next_time_s() - dt, next_time_s()].
  /// `accel_breaks_s`: times strictly inside the interval where the angular acceleration jumps
  /// (ascending; used only with the size effect). Throws std::invalid_argument if they are not
  /// ascending inside the interval.
  ImuIncrement next(const StateAt& state_at, const std::vector<double>& accel_breaks_s = {});
  /// End time of the interval the next call to next() covers: (samples() + 1) / rate_hz.
  double next_time_s() const;
  /// Start time of that interval.
  double interval_start_s() const;
  uint64_t samples() const { return k_; }
  double dt_s() const { return dt_s_; }
  /// True if next() samples the state inside the interval (size effect), not only at its ends.
  bool needs_interior_states() const;
  /// The sensor noise continues from the stream of `seed` (TruthSensor::reseed_noise).
  void reseed_noise(uint64_t seed);

 private:
  double dt_s_;
  uint64_t k_ = 0;
  std::unique_ptr<TruthKinematics> kin_;
  std::unique_ptr<TruthSensor> sensor_;
  bool have_prev_ = false;
  Eigen::Matrix3d C_prev_ = Eigen::Matrix3d::Identity();
};

}  // namespace imucal::calib::sim
