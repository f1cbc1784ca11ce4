#include "sim/spline_trajectory.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>

#include "core/errors.h"

namespace lisfm {
namespace sim {
namespace {

// Cumulative cubic B-spline basis: B~(u) = C * [1, u, u^2, u^3]^T and its
// first and second derivatives with respect to u (Sommer et al. 2020, Eq. 5).
void CumulativeBasis(double u, Vec4* b, Vec4* db, Vec4* ddb) {
  Eigen::Matrix4d c;
  c << 6, 0, 0, 0, 5, 3, -3, 1, 1, 3, 3, -2, 0, 0, 0, 1;
  c /= 6.0;
  *b = c * Vec4(1, u, u * u, u * u * u);
  *db = c * Vec4(0, 1, 2 * u, 3 * u * u);
  *ddb = c * Vec4(0, 0, 2, 6 * u);
}

// Plain (non-cumulative) uniform cubic B-spline basis weights at u.
Vec4 Basis(double u) {
  const double u2 = u * u, u3 = u2 * u;
  return Vec4((1 - 3 * u + 3 * u2 - u3) / 6.0, (4 - 6 * u2 + 3 * u3) / 6.0,
              (1 + 3 * u + 3 * u2 - 3 * u3) / 6.0, u3 / 6.0);
}

}  // namespace

SplineTrajectory::SplineTrajectory(TimestampNs start_ns,
                                   double dt_s,
                                   std::vector<Quat> rotations,
                                   std::vector<Vec3> positions)
    : start_ns_(start_ns), dt_(dt_s), rotations_(std::move(rotations)),
      positions_(std::move(positions)) {
  THROW_CHECK_GT(dt_, 0.0);
  THROW_CHECK_EQ(rotations_.size(), positions_.size());
  THROW_CHECK_GE(rotations_.size(), 4u);
  for (Quat& q : rotations_) q.normalize();
  // Keep consecutive control quaternions in the same hemisphere.
  for (size_t i = 1; i < rotations_.size(); ++i) {
    if (rotations_[i].dot(rotations_[i - 1]) < 0) rotations_[i].coeffs() *= -1;
  }
}

double SplineTrajectory::duration_s() const {
  return static_cast<double>(positions_.size() - 3) * dt_;
}

TimestampNs SplineTrajectory::end_ns() const {
  return start_ns_ + static_cast<TimestampNs>(std::floor(duration_s() * 1e9));
}

TrajectorySample SplineTrajectory::Evaluate(TimestampNs t_ns) const {
  t_ns = std::clamp(t_ns, start_ns_, end_ns());
  return EvaluateSeconds(static_cast<double>(t_ns - start_ns_) * 1e-9);
}

TrajectorySample SplineTrajectory::EvaluateSeconds(double t) const {
  const double s = t / dt_;
  const int max_segment = static_cast<int>(positions_.size()) - 4;
  int i = std::min(static_cast<int>(std::floor(s)), max_segment);
  i = std::max(i, 0);
  const double u = s - i;
  Vec4 b, db, ddb;
  CumulativeBasis(u, &b, &db, &ddb);
  const double inv_dt = 1.0 / dt_;
  TrajectorySample out;
  // Position: p = p_i + sum_j B~_j (p_{i+j} - p_{i+j-1}).
  Vec3 p = positions_[i], v = Vec3::Zero(), a = Vec3::Zero();
  for (int j = 1; j < 4; ++j) {
    const Vec3 d = positions_[i + j] - positions_[i + j - 1];
    p += b[j] * d;
    v += db[j] * inv_dt * d;
    a += ddb[j] * inv_dt * inv_dt * d;
  }
  // Rotation: R = R_i prod_j Exp(B~_j d_j); omega recursion (Sommer Eq. 17):
  // omega_j = A_j^T omega_{j-1} + dB~_j d_j.
  Quat q = rotations_[i];
  Vec3 omega = Vec3::Zero();
  for (int j = 1; j < 4; ++j) {
    const Vec3 d = so3::Log(rotations_[i + j - 1].conjugate() * rotations_[i + j]);
    const Quat a_j = so3::Exp(b[j] * d);
    q = q * a_j;
    omega = a_j.conjugate() * omega + db[j] * inv_dt * d;
  }
  q.normalize();
  out.world_from_imu = SE3(q, p);
  out.velocity_world = v;
  out.acceleration_world = a;
  out.angular_velocity_body = omega;
  return out;
}

void SplineTrajectory::TransformWorld(const SE3& new_world_from_world) {
  for (size_t i = 0; i < positions_.size(); ++i) {
    const SE3 pose = new_world_from_world * SE3(rotations_[i], positions_[i]);
    rotations_[i] = pose.rotation();
    positions_[i] = pose.translation();
  }
}

SplineTrajectory SplineTrajectory::Fit(const Trajectory& samples, double dt_s) {
  THROW_CHECK_GE(samples.size(), 2u);
  const TimestampNs start_ns = samples.start_ns();
  const double duration = NsToSeconds(samples.end_ns() - start_ns);
  const int segments = std::max(1, static_cast<int>(std::floor(duration / dt_s)));
  const int n = segments + 3;
  // Rotations: control j at t = (j - 1) dt, clamped into the sample range.
  std::vector<Quat> rotations(n);
  for (int j = 0; j < n; ++j) {
    const double t = std::clamp((j - 1) * dt_s, 0.0, duration);
    rotations[j] = samples.Interpolate(start_ns + SecondsToNs(t))->rotation();
  }
  // Positions: min sum ||p(t_k) - x_k||^2 + lambda sum ||p_{j-1} - 2 p_j + p_{j+1}||^2.
  std::vector<Eigen::Triplet<double>> a_entries;
  int row = 0;
  std::vector<Vec3> target_rows;
  for (const StampedPose& sp : samples.poses()) {
    const double t = NsToSeconds(sp.t_ns - start_ns);
    const double s = t / dt_s;
    const int i = std::clamp(static_cast<int>(std::floor(s)), 0, n - 4);
    const Vec4 w = Basis(s - i);
    for (int k = 0; k < 4; ++k) a_entries.emplace_back(row, i + k, w[k]);
    target_rows.push_back(sp.pose.translation());
    ++row;
  }
  const double lambda = 0.05;
  for (int j = 1; j + 1 < n; ++j) {
    a_entries.emplace_back(row, j - 1, lambda);
    a_entries.emplace_back(row, j, -2 * lambda);
    a_entries.emplace_back(row, j + 1, lambda);
    target_rows.push_back(Vec3::Zero());
    ++row;
  }
  Eigen::SparseMatrix<double> a(row, n);
  a.setFromTriplets(a_entries.begin(), a_entries.end());
  Eigen::MatrixXd b(row, 3);
  for (int r = 0; r < row; ++r) b.row(r) = target_rows[r].transpose();
  Eigen::SparseMatrix<double> ata = a.transpose() * a;
  // Tiny ridge so control points without samples stay determined.
  for (int j = 0; j < n; ++j) ata.coeffRef(j, j) += 1e-9;
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(ata);
  THROW_CHECK_MSG(solver.info() == Eigen::Success, "spline fit: factorisation failed");
  const Eigen::MatrixXd x = solver.solve(a.transpose() * b);
  std::vector<Vec3> positions(n);
  for (int j = 0; j < n; ++j) positions[j] = x.row(j).transpose();
  return SplineTrajectory(start_ns, dt_s, std::move(rotations), std::move(positions));
}

}  // namespace sim
}  // namespace lisfm
