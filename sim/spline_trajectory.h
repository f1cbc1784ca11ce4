// A smooth continuous-time trajectory world_from_imu(t) with analytic
// derivatives: a uniform cumulative cubic B-spline on SO(3) (Kim et al. 1995;
// body angular velocity by the recursion of Sommer et al., "Efficient
// Derivative Computation for Cumulative B-Splines on Lie Groups", CVPR 2020,
// Eq. 17-18) and a uniform cubic B-spline on R^3 for the position. Both are
// C2, so velocity, acceleration and angular velocity are continuous.
//
// Time is in seconds relative to start_ns(); control point j sits at
// t = (j - 1) * dt, so N control points cover [0, (N - 3) * dt].
#pragma once

#include <vector>

#include "core/geometry.h"
#include "core/time.h"
#include "core/trajectory.h"

namespace lisfm {
namespace sim {

struct TrajectorySample {
  SE3 world_from_imu;
  Vec3 velocity_world;          // m/s
  Vec3 acceleration_world;      // m/s^2 (kinematic, gravity not included)
  Vec3 angular_velocity_body;   // rad/s, omega with R^T dR/dt = Hat(omega)
};

class SplineTrajectory {
 public:
  SplineTrajectory() = default;
  // `rotations` and `positions` are the control points (same count, >= 4).
  SplineTrajectory(TimestampNs start_ns,
                   double dt_s,
                   std::vector<Quat> rotations,
                   std::vector<Vec3> positions);

  // Fits control points to time-stamped poses (e.g. a TUM ground truth):
  // positions by linear least squares on the B-spline basis (with a small
  // smoothness term), rotations by placing the control rotations at the
  // slerp-interpolated samples (the cumulative spline then passes within the
  // smoothing of the samples). `dt_s` is the knot spacing.
  static SplineTrajectory Fit(const Trajectory& samples, double dt_s);

  TimestampNs start_ns() const { return start_ns_; }
  TimestampNs end_ns() const;
  double duration_s() const;
  double dt_s() const { return dt_; }

  // Evaluates at t_ns (clamped to [start_ns, end_ns]).
  TrajectorySample Evaluate(TimestampNs t_ns) const;
  SE3 Pose(TimestampNs t_ns) const { return Evaluate(t_ns).world_from_imu; }

  // Applies world' = offset * world to all control points.
  void TransformWorld(const SE3& new_world_from_world);

  const std::vector<Vec3>& position_controls() const { return positions_; }

 private:
  TrajectorySample EvaluateSeconds(double t) const;

  TimestampNs start_ns_ = 0;
  double dt_ = 0.1;
  std::vector<Quat> rotations_;
  std::vector<Vec3> positions_;
};

}  // namespace sim
}  // namespace lisfm
