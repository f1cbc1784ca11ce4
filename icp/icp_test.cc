#include "icp/icp.h"

#include <cmath>

#include <Eigen/Eigenvalues>
#include <gtest/gtest.h>

#include "core/errors.h"
#include "icp/icp_covariance.h"
#include "icp/testing/scenes.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

// Matches within 0.5 m, no normal-angle or planarity test.
constexpr MatchCriteria kWithin50cm{0.5f, 0.f, 0.f};

const Eigen::Vector3d kRoom(3.0, 2.0, 4.0);  // half sizes of the synthetic room (m)

// Analytic point-to-plane Jacobian vs central differences of r(T Exp(xi)).
TEST(PointToPlaneResidual, JacobianMatchesNumeric) {
  for (int trial = 0; trial < 20; ++trial) {
    const SE3 T = test::RandomPose(1.0, 2.0);
    std::normal_distribution<double> g(0.0, 1.0);
    const Vec3 p(g(test::Rng()), g(test::Rng()), g(test::Rng()));
    const Vec3 q(g(test::Rng()), g(test::Rng()), g(test::Rng()));
    const Vec3 n = Vec3(g(test::Rng()), g(test::Rng()), g(test::Rng())).normalized();
    Eigen::Matrix<double, 1, 6> J;
    PointToPlaneResidual(T, p, q, n, &J);
    const Eigen::MatrixXd numeric = test::NumericJacobian(
        [&](const Eigen::VectorXd& xi) {
          return Eigen::VectorXd::Constant(
              1, PointToPlaneResidual(T * SE3::Exp(Vec6(xi)), p, q, n, nullptr));
        },
        Eigen::VectorXd::Zero(6));
    // Central differences with step 1e-6 are accurate to ~1e-9 here.
    EXPECT_LT((J - numeric).cwiseAbs().maxCoeff(), 1e-7) << J << "\n" << numeric;
  }
}

// The same noise-free points moved by a known transform are registered exactly
// (float storage limits the residual to ~1e-7 m; tolerance 1e-5 m / 1e-5 rad).
TEST(RegisterPointToPlane, ExactRecoveryKdTree) {
  const PointSet target = test::SampleBoxRoom(kRoom, 3000, 0.0, test::Rng());
  const SE3 truth(so3::Exp(Vec3(0.05, -0.08, 0.1)), Vec3(0.2, -0.15, 0.1));
  const PointSet source = test::Transformed(target, truth.Inverse());
  const KdTreeTarget model(target, NormalOptions());
  IcpOptions options;
  options.max_iterations = 100;
  // Exactness needs a stricter stop than the default 1e-4 (1e-6: float points limit steps to ~1e-7).
  options.convergence_rotation_rad = 1e-6;
  options.convergence_translation_m = 1e-6;
  const IcpResult result = RegisterPointToPlane(source, model, SE3(), options);
  EXPECT_TRUE(result.converged) << result.message;
  EXPECT_FALSE(result.degenerate);
  EXPECT_EQ(result.num_inliers, source.size());
  EXPECT_LT(result.rmse_m, 1e-5);
  EXPECT_TRUE(test::PosesNear(result.target_from_source, truth, 1e-5, 1e-5));
}

// The warm-started search returns exactly Match()'s result, whatever the hint:
// kNoHint, the true nearest point, a stale neighbour, a far point, or a point
// beyond the max distance.
TEST(KdTreeTarget, MatchWithHintEqualsMatch) {
  const PointSet target = test::SampleBoxRoom(kRoom, 2000, 0.01, test::Rng());
  const KdTreeTarget model(target, NormalOptions());
  std::normal_distribution<float> g(0.f, 1.f);
  std::uniform_int_distribution<uint32_t> any(0, static_cast<uint32_t>(target.size() - 1));
  size_t matched = 0;
  for (int trial = 0; trial < 2000; ++trial) {
    const Eigen::Vector3f query =
        target[any(test::Rng())] + 0.2f * Eigen::Vector3f(g(test::Rng()), g(test::Rng()), g(test::Rng()));
    Eigen::Vector3f q0, n0;
    const bool ok0 = model.Match(query, Eigen::Vector3f::Zero(), kWithin50cm, &q0, &n0);
    uint32_t nearest = IcpTarget::kNoHint;
    if (ok0) {
      float d2 = 0;
      ASSERT_TRUE(model.tree().Nearest(query, &nearest, &d2));
    }
    for (uint32_t hint : {IcpTarget::kNoHint, nearest, any(test::Rng()), any(test::Rng())}) {
      Eigen::Vector3f q1, n1;
      uint32_t h = hint;
      const bool ok1 = model.MatchWithHint(query, Eigen::Vector3f::Zero(), kWithin50cm, &q1, &n1, &h);
      ASSERT_EQ(ok0, ok1) << "trial " << trial << " hint " << hint;
      if (ok0) {
        EXPECT_EQ(q0, q1) << "trial " << trial << " hint " << hint;
        EXPECT_EQ(n0, n1);
        EXPECT_EQ(h, nearest);  // the hint now names the match
      }
    }
    matched += ok0 ? 1 : 0;
  }
  EXPECT_GT(matched, 1000u);  // the queries exercise both outcomes
  EXPECT_LT(matched, 2000u);
}

// The tracked match (searches skipped while a query stays within the margin of
// its last search) returns exactly Match()'s result along random walks whose
// steps range from 0.1 mm to 0.3 m, i.e. both inside and far outside the margins;
// the walks must exercise both paths (skipped searches leave the anchor alone).
TEST(KdTreeTarget, MatchTrackedEqualsMatch) {
  const PointSet target = test::SampleBoxRoom(kRoom, 2000, 0.01, test::Rng());
  const KdTreeTarget model(target, NormalOptions());
  std::normal_distribution<float> g(0.f, 1.f);
  std::uniform_real_distribution<float> log_step(std::log(1e-4f), std::log(0.3f));
  std::uniform_int_distribution<uint32_t> any(0, static_cast<uint32_t>(target.size() - 1));
  size_t skipped = 0, searched = 0, matched = 0, steps = 0;
  for (int walk = 0; walk < 200; ++walk) {
    const Eigen::Vector3f offset(g(test::Rng()), g(test::Rng()), g(test::Rng()));
    Eigen::Vector3f query = target[any(test::Rng())] + 0.05f * offset;
    IcpTarget::MatchState state;
    for (int step = 0; step < 30; ++step, ++steps) {
      const Eigen::Vector3f dir(g(test::Rng()), g(test::Rng()), g(test::Rng()));
      query += std::exp(log_step(test::Rng())) * dir.normalized();
      Eigen::Vector3f q0, n0, q1, n1;
      const bool ok0 = model.Match(query, Eigen::Vector3f::Zero(), kWithin50cm, &q0, &n0);
      const Eigen::Vector3f anchor_before = state.anchor;
      const bool tracked_before = state.margin_m > 0;
      const bool ok1 =
          model.MatchTracked(query, Eigen::Vector3f::Zero(), kWithin50cm, &q1, &n1, &state);
      ASSERT_EQ(ok0, ok1) << "walk " << walk << " step " << step;
      if (ok0) {
        EXPECT_EQ(q0, q1) << "walk " << walk << " step " << step;
        EXPECT_EQ(n0, n1);
        uint32_t nearest = 0;
        float d2 = 0;
        ASSERT_TRUE(model.tree().Nearest(query, &nearest, &d2));
        EXPECT_EQ(state.index, nearest);
        ++matched;
      }
      if (tracked_before && state.anchor == anchor_before && query != anchor_before) {
        ++skipped;
      } else {
        ++searched;
      }
    }
  }
  // Both outcomes and both paths occur (counts are loose: the walks are random).
  EXPECT_GT(matched, steps / 4);
  EXPECT_LT(matched, steps);
  EXPECT_GT(skipped, steps / 10);
  EXPECT_GT(searched, steps / 10);
}

// Re-solving on fixed matches (max_inner_iterations) and the step extrapolation
// speed the iteration up but keep its fixed point: from a 0.5 m / 0.2 rad offset
// with noisy points and a Huber kernel, both settings land on the same estimate
// (within the 1e-6 convergence thresholds used here, x10 for the two paths'
// different approach), with no more associations when re-solving. The returned
// Hessian (from the last association's matches) equals one recomputed from fresh
// matches at the estimate to 1e-3 relative.
// The room sampled twice with 5 mm noise: a target, and a source displaced by truth.
struct NoisyRoomPair {
  PointSet target, source;
};
NoisyRoomPair SampleNoisyRoomPair(int target_points, int source_points, const SE3& truth) {
  NoisyRoomPair pair;
  pair.target = test::SampleBoxRoom(kRoom, target_points, 0.005, test::Rng());
  pair.source = test::Transformed(test::SampleBoxRoom(kRoom, source_points, 0.005, test::Rng()),
                                  truth.Inverse());
  return pair;
}

// Up to 200 associations, converged when a step is below `tolerance` (rad and m).
IcpOptions TightOptions(double tolerance) {
  IcpOptions options;
  options.max_iterations = 200;
  options.convergence_rotation_rad = tolerance;
  options.convergence_translation_m = tolerance;
  return options;
}

// IcpOptions::field_of_view_gate: a target scanned from the origin within
// elevations of +-15 deg (a cylinder wall of radius 5 m); points the target could
// not have seen (above its band, or beyond its farthest point) get no match with
// the gate, the nearest point without it; points in view match the same either way.
TEST(KdTreeTarget, FieldOfViewGate) {
  PointSet wall;
  for (int a = 0; a < 360; ++a) {
    for (int e = -15; e <= 15; ++e) {
      const double az = a * M_PI / 180.0, el = e * M_PI / 180.0;
      wall.emplace_back(Eigen::Vector3f(static_cast<float>(5.0 * std::cos(az)),
                                        static_cast<float>(5.0 * std::sin(az)),
                                        static_cast<float>(5.0 * std::tan(el))));
    }
  }
  const KdTreeTarget target(wall, NormalOptions());
  MatchCriteria gated{3.f, 0.f, 0.f};
  gated.field_of_view_gate = true;
  const MatchCriteria open{3.f, 0.f, 0.f};
  // In view (elevation ~5 deg, 4.9 m out): matched with and without the gate.
  const Eigen::Vector3f in_view(4.9f, 0.02f, 0.43f);
  // Above the band (elevation ~21 deg): the wall's top ring is within 3 m.
  const Eigen::Vector3f above(4.6f, 0.f, 1.8f);
  // Beyond the farthest target point (5.2 m range) but within 3 m of the wall.
  const Eigen::Vector3f beyond(5.6f, 0.f, 0.f);
  Eigen::Vector3f q, n, q_gated, n_gated;
  ASSERT_TRUE(target.Match(in_view, Eigen::Vector3f::Zero(), open, &q, &n));
  ASSERT_TRUE(target.Match(in_view, Eigen::Vector3f::Zero(), gated, &q_gated, &n_gated));
  EXPECT_EQ(q, q_gated);
  EXPECT_TRUE(target.Match(above, Eigen::Vector3f::Zero(), open, &q, &n));
  EXPECT_FALSE(target.Match(above, Eigen::Vector3f::Zero(), gated, &q, &n));
  EXPECT_TRUE(target.Match(beyond, Eigen::Vector3f::Zero(), open, &q, &n));
  EXPECT_FALSE(target.Match(beyond, Eigen::Vector3f::Zero(), gated, &q, &n));
  // The other entry points gate the same way.
  uint32_t hint = IcpTarget::kNoHint;
  EXPECT_FALSE(target.MatchWithHint(above, Eigen::Vector3f::Zero(), gated, &q, &n, &hint));
  IcpTarget::MatchState out_state, in_state;
  EXPECT_FALSE(target.MatchTracked(beyond, Eigen::Vector3f::Zero(), gated, &q, &n, &out_state));
  EXPECT_TRUE(target.MatchTracked(in_view, Eigen::Vector3f::Zero(), gated, &q, &n, &in_state));
  // MatchTracked keeps its first decision for a source point: later queries of the
  // same point are not re-gated (no drift towards poses with fewer points in view).
  EXPECT_FALSE(target.MatchTracked(in_view, Eigen::Vector3f::Zero(), gated, &q, &n, &out_state));
  EXPECT_TRUE(target.MatchTracked(above, Eigen::Vector3f::Zero(), gated, &q, &n, &in_state));
}

// IcpOptions::visibility_gate_m: a target scanned from the origin sees a small
// near wall (x = 3 m) in front of a large far wall (x = 6 m). A source point behind
// the near wall (hidden from the target's viewpoint) gets no match with the gate;
// points in front of it, within the tolerance, or beside it match as without.
TEST(KdTreeTarget, VisibilityGate) {
  PointSet points;
  for (int i = -50; i <= 50; ++i) {
    for (int j = -50; j <= 50; ++j) points.emplace_back(3.f, 0.01f * i, 0.01f * j);
  }
  for (int i = -60; i <= 60; ++i) {
    for (int j = -60; j <= 60; ++j) points.emplace_back(6.f, 0.05f * i, 0.05f * j);
  }
  const KdTreeTarget target(points, NormalOptions());
  MatchCriteria gated{3.f, 0.f, 0.f};
  gated.visibility_gate_m = 0.1f;
  const MatchCriteria open{3.f, 0.f, 0.f};
  const Eigen::Vector3f hidden(3.5f, 0.1f, 0.1f);    // 0.5 m behind the near wall
  const Eigen::Vector3f front(2.9f, 0.1f, 0.1f);     // in front of it
  const Eigen::Vector3f tolerated(3.12f, 0.1f, 0.1f);  // behind, within 0.1 m + 2 %
  const Eigen::Vector3f beside(5.f, 2.f, 0.f);       // in front of the far wall
  Eigen::Vector3f q, n, q_gated, n_gated;
  EXPECT_TRUE(target.Match(hidden, Eigen::Vector3f::Zero(), open, &q, &n));
  EXPECT_FALSE(target.Match(hidden, Eigen::Vector3f::Zero(), gated, &q, &n));
  for (const Eigen::Vector3f& p : {front, tolerated, beside}) {
    ASSERT_TRUE(target.Match(p, Eigen::Vector3f::Zero(), open, &q, &n));
    ASSERT_TRUE(target.Match(p, Eigen::Vector3f::Zero(), gated, &q_gated, &n_gated));
    EXPECT_EQ(q, q_gated);
  }
  uint32_t hint = IcpTarget::kNoHint;
  EXPECT_FALSE(target.MatchWithHint(hidden, Eigen::Vector3f::Zero(), gated, &q, &n, &hint));
  // MatchTracked decides once per source point, as the field-of-view gate.
  IcpTarget::MatchState hidden_state, front_state;
  EXPECT_FALSE(target.MatchTracked(hidden, Eigen::Vector3f::Zero(), gated, &q, &n, &hidden_state));
  EXPECT_FALSE(target.MatchTracked(front, Eigen::Vector3f::Zero(), gated, &q, &n, &hidden_state));
  EXPECT_TRUE(target.MatchTracked(front, Eigen::Vector3f::Zero(), gated, &q, &n, &front_state));
  EXPECT_TRUE(target.MatchTracked(hidden, Eigen::Vector3f::Zero(), gated, &q, &n, &front_state));
  // The range image is seen from the target's viewpoint. From x = 4.5 m (between
  // the walls) the point behind the near wall is in front of it, and a point at
  // x = 2.5 m is behind it.
  const KdTreeTarget between(points, NormalOptions(), Eigen::Vector3f(4.5f, 0.f, 0.f));
  EXPECT_TRUE(between.Match(hidden, Eigen::Vector3f::Zero(), gated, &q, &n));
  EXPECT_FALSE(between.Match(Eigen::Vector3f(2.5f, 0.1f, 0.1f), Eigen::Vector3f::Zero(), gated, &q, &n));
  IcpOptions bad;
  bad.visibility_gate_m = -0.1;
  EXPECT_FALSE(bad.Check());
}

// A spinning LiDAR 1.4 m above a floor (z = -1.4 m; rings every 1 deg from -2.5 to
// -19.5 deg, one in each 1 deg elevation bin of the range image; 0.2 deg azimuth
// steps), seen from `origin`, with an optional wall patch (x = 4 m, |y| <= 1 m,
// z <= 1 m) in front of the origin: the first surface each ray meets.
PointSet ScanFloor(const Eigen::Vector3f& origin, bool with_wall) {
  PointSet points;
  for (int ring = 0; ring < 18; ++ring) {
    const double elevation = (-2.5 - ring) * M_PI / 180.0;
    for (int a = 0; a < 1800; ++a) {
      const double azimuth = a * 0.2 * M_PI / 180.0;
      const Eigen::Vector3f u(static_cast<float>(std::cos(elevation) * std::cos(azimuth)),
                              static_cast<float>(std::cos(elevation) * std::sin(azimuth)),
                              static_cast<float>(std::sin(elevation)));
      float t = (-1.4f - origin.z()) / u.z();
      if (with_wall && u.x() > 0) {
        const float t_wall = (4.f - origin.x()) / u.x();
        const Eigen::Vector3f w = origin + t_wall * u;
        if (t_wall > 0 && t_wall < t && std::abs(w.y()) <= 1.f && w.z() <= 1.f) t = t_wall;
      }
      if (t < 30.f) points.push_back(origin + t * u);
    }
  }
  return points;
}

// IcpOptions::visibility_follows_surface: the floor points of a second scan (6 m ahead)
// that lie 8-20 m from the target's sensor are visible to it, but at that grazing
// incidence the nearest-range gate (r <= 1.02 nearest + 0.1 m per 0.5 x 1 deg bin)
// rejects those beyond its bin's ring (30 % here); following the surface keeps them
// all, and still rejects the floor points hidden behind a wall.
TEST(KdTreeTarget, VisibilityGateFollowsGrazingSurfaces) {
  const KdTreeTarget target(ScanFloor(Eigen::Vector3f::Zero(), false), NormalOptions{20, 1.0});
  const MatchCriteria open{5.f, 0.f, 0.f};
  MatchCriteria nearest_range = open;
  nearest_range.visibility_gate_m = 0.1f;
  MatchCriteria follows = nearest_range;
  follows.visibility_follows_surface = true;
  int total = 0, kept_nearest = 0, kept_follows = 0;
  Eigen::Vector3f q, n;
  for (const Eigen::Vector3f& p : ScanFloor(Eigen::Vector3f(6.f, 0.f, 0.f), false)) {
    const float r = p.norm();
    if (r < 8.f || r > 20.f || !target.Match(p, Eigen::Vector3f::Zero(), open, &q, &n)) continue;
    ++total;
    kept_nearest += target.Match(p, Eigen::Vector3f::Zero(), nearest_range, &q, &n) ? 1 : 0;
    kept_follows += target.Match(p, Eigen::Vector3f::Zero(), follows, &q, &n) ? 1 : 0;
  }
  ASSERT_GT(total, 1000);
  EXPECT_LT(kept_nearest, 0.8 * total);  // 70 %: the scene exercises the defect
  EXPECT_GT(kept_follows, 0.98 * total);
  // Behind a wall: floor points the walled target cannot see.
  const KdTreeTarget walled(ScanFloor(Eigen::Vector3f::Zero(), true), NormalOptions{20, 1.0});
  int hidden = 0, hidden_kept = 0;
  for (float x = 6.f; x <= 12.f; x += 0.25f) {
    for (float y = -0.5f; y <= 0.5f; y += 0.25f) {
      const Eigen::Vector3f p(x, y, -1.4f);
      if (!walled.Match(p, Eigen::Vector3f::Zero(), open, &q, &n)) continue;
      ++hidden;
      hidden_kept += walled.Match(p, Eigen::Vector3f::Zero(), follows, &q, &n) ? 1 : 0;
    }
  }
  ASSERT_GT(hidden, 50);
  EXPECT_EQ(hidden_kept, 0);
}

// IcpOptions::min_normal_contrast: far floor points whose neighbours lie on one ring
// (planarity (l1 - l0) / l2 below 0.1) have a determined, vertical normal and pass a
// contrast gate of 0.5; points on a straight line do not.
TEST(KdTreeTarget, NormalContrastKeepsRingLineNormals) {
  const KdTreeTarget target(ScanFloor(Eigen::Vector3f::Zero(), false), NormalOptions{20, 1.0});
  int far = 0, low_planarity = 0, contrast_kept = 0;
  double max_tilt_deg = 0;
  for (size_t i = 0; i < target.size(); i += 7) {
    const Eigen::Vector3f& p = target.tree().points()[i];
    if (p.head<2>().norm() < 12.f) continue;
    Eigen::Vector3f n;
    float planarity = 0.f, contrast = 0.f;
    target.NormalAt(i, &n, &planarity, &contrast);
    ++far;
    low_planarity += planarity < 0.1f ? 1 : 0;
    if (contrast >= 0.5f) {
      ++contrast_kept;
      const double tilt_deg = std::acos(std::min(1.f, std::abs(n.z()))) * 180.0 / M_PI;
      max_tilt_deg = std::max(max_tilt_deg, tilt_deg);
    }
  }
  ASSERT_GT(far, 500);
  EXPECT_GT(low_planarity, 0.9 * far);
  EXPECT_GT(contrast_kept, 0.95 * far);
  EXPECT_LT(max_tilt_deg, 1.0);
  PointSet line;
  for (int i = 0; i < 100; ++i) line.emplace_back(0.02f * i, 1.f, 0.f);
  const KdTreeTarget straight(line, NormalOptions{20, 1.0});
  Eigen::Vector3f n;
  float planarity = 0.f, contrast = 0.f;
  straight.NormalAt(50, &n, &planarity, &contrast);
  EXPECT_LT(contrast, 0.5f);
  IcpOptions bad;
  bad.min_normal_contrast = 1.5;
  EXPECT_FALSE(bad.Check());
}

TEST(RegisterPointToPlane, InnerIterationsKeepTheFixedPoint) {
  const SE3 truth(so3::Exp(Vec3(0.1, -0.12, 0.15)), Vec3(0.4, -0.25, 0.2));
  const auto [target, source] = SampleNoisyRoomPair(3000, 1500, truth);
  const KdTreeTarget model(target, NormalOptions());
  IcpOptions options = TightOptions(1e-6);
  options.max_inner_iterations = 0;
  const IcpResult plain = RegisterPointToPlane(source, model, SE3(), options);
  options.max_inner_iterations = 5;
  const IcpResult inner = RegisterPointToPlane(source, model, SE3(), options);
  ASSERT_TRUE(plain.converged) << plain.message;
  ASSERT_TRUE(inner.converged) << inner.message;
  EXPECT_TRUE(test::PosesNear(inner.target_from_source, plain.target_from_source, 1e-5, 1e-5));
  EXPECT_TRUE(test::PosesNear(inner.target_from_source, truth, 2e-3, 5e-3));  // 5 mm noise
  EXPECT_LE(inner.iterations, plain.iterations);
  // Fresh matches at the returned estimate.
  Mat6 fresh = Mat6::Zero();
  const Eigen::Matrix3f R = inner.target_from_source.RotationMatrix().cast<float>();
  const Eigen::Vector3f t = inner.target_from_source.translation().cast<float>();
  for (const Eigen::Vector3f& p : source) {
    Eigen::Vector3f q, n;
    if (!model.Match(R * p + t, Eigen::Vector3f::Zero(), MatchCriteria{1.f, 0.f, 0.f}, &q, &n)) continue;
    Eigen::Matrix<double, 1, 6> J;
    const double r = PointToPlaneResidual(inner.target_from_source, p.cast<double>(),
                                          q.cast<double>(), n.cast<double>(), &J);
    fresh += RobustWeight(RobustKernel::kHuber, r, options.kernel_scale_m) * J.transpose() * J;
  }
  EXPECT_LT((inner.hessian - fresh).norm(), 1e-3 * fresh.norm());
}

// The coarse-to-fine levels only change the path: with tight convergence
// thresholds the runs with all three coarse levels (12000 source points: 750 at
// 1/16, 1500 at 1/8, 3000 at 1/4, all >= coarse_min_points 600), with two, and
// without any (coarse_min_points above the point count) reach the same estimate.
TEST(RegisterPointToPlane, CoarseLevelsKeepTheFixedPoint) {
  const SE3 truth(so3::Exp(Vec3(0.08, -0.1, 0.12)), Vec3(0.35, -0.2, 0.15));
  const auto [target, source] = SampleNoisyRoomPair(24000, 12000, truth);
  const KdTreeTarget model(target, NormalOptions());
  IcpOptions options = TightOptions(1e-7);
  ASSERT_EQ(options.coarse_min_points, 600);
  ASSERT_EQ(options.coarse_levels, 3);
  const IcpResult three = RegisterPointToPlane(source, model, SE3(), options);
  options.coarse_levels = 2;
  const IcpResult two = RegisterPointToPlane(source, model, SE3(), options);
  options.coarse_min_points = 100000;
  const IcpResult flat = RegisterPointToPlane(source, model, SE3(), options);
  for (const IcpResult* r : {&three, &two, &flat}) {
    ASSERT_TRUE(r->converged) << r->message;
    EXPECT_TRUE(test::PosesNear(r->target_from_source, flat.target_from_source, 1e-6, 1e-6));
  }
  EXPECT_TRUE(test::PosesNear(three.target_from_source, truth, 2e-3, 5e-3));  // 5 mm noise
}

// Projective association on rendered depth maps of a room: the source camera is
// displaced by a known pose. Point-to-plane is exact on planes, but nearest-pixel
// matching near the room's edges pairs a few points with the adjacent wall's
// normal, which leaves ~0.1 mm of bias: tolerance 0.5 mm / 0.5 mrad (the
// displacement is 70 mm / 37 mrad).
TEST(RegisterPointToPlane, ExactRecoveryProjective) {
  const PinholeIntrinsics K{150, 150, 80, 60, 160, 120};
  const SE3 world_from_target(so3::Exp(Vec3(0.1, 0.6, 0.0)), Vec3(0.3, 0.2, -1.0));
  const SE3 target_from_source(so3::Exp(Vec3(0.02, -0.03, 0.01)), Vec3(0.05, -0.03, 0.04));
  const PointSet target_map = test::RenderBoxRoom(kRoom, world_from_target, K);
  const PointSet source_map = test::RenderBoxRoom(kRoom, world_from_target * target_from_source, K);
  PointSet source;
  for (size_t i = 0; i < source_map.size(); i += 3) source.push_back(source_map[i]);
  const ProjectiveTarget model(target_map, K);
  IcpOptions options;
  options.max_correspondence_distance_m = 0.3;
  options.max_iterations = 100;
  const IcpResult result = RegisterPointToPlane(source, model, SE3(), options);
  EXPECT_TRUE(result.converged) << result.message;
  EXPECT_TRUE(test::PosesNear(result.target_from_source, target_from_source, 5e-4, 5e-4));
}

// 25 % outliers scattered in the room: each robust kernel still recovers the pose
// from noisy, independently sampled clouds within 2 mm / 0.1 deg (the noise is
// 3 mm on 20k points; a bias from outliers would be centimetres).
TEST(RegisterPointToPlane, RobustKernelsRejectOutliers) {
  const PointSet target = test::SampleBoxRoom(kRoom, 4000, 0.003, test::Rng());
  const SE3 truth(so3::Exp(Vec3(0.02, 0.03, -0.04)), Vec3(0.1, 0.05, -0.1));
  PointSet source =
      test::Transformed(test::SampleBoxRoom(kRoom, 4000, 0.003, test::Rng()), truth.Inverse());
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const size_t n_out = source.size() / 4;
  for (size_t i = 0; i < n_out; ++i) {
    source.push_back(Eigen::Vector3f(u(test::Rng()) * kRoom.x(), u(test::Rng()) * kRoom.y(),
                                     u(test::Rng()) * kRoom.z()));
  }
  const KdTreeTarget model(target, NormalOptions());
  for (const std::string kernel : {"huber", "cauchy", "geman_mcclure"}) {
    IcpOptions options;
    options.kernel = kernel;
    options.kernel_scale_m = 0.01;
    options.max_correspondence_distance_m = 0.5;
    options.max_iterations = 100;
    const IcpResult result = RegisterPointToPlane(source, model, SE3(), options);
    EXPECT_TRUE(result.converged) << kernel << ": " << result.message;
    EXPECT_TRUE(test::PosesNear(result.target_from_source, truth, 0.1 * M_PI / 180, 0.002))
        << kernel;
  }
}

// A single plane constrains only 3 DoF: reported degenerate, not converged.
TEST(RegisterPointToPlane, SinglePlaneIsDegenerate) {
  PointSet plane;
  test::SamplePlane(2, 0.0, Eigen::Vector3d(-3, -3, 0), Eigen::Vector3d(3, 3, 0), 3000, 0.002,
                    test::Rng(), &plane);
  const PointSet source = test::Transformed(plane, SE3(Quat::Identity(), Vec3(0, 0, 0.05)));
  const KdTreeTarget model(plane, NormalOptions());
  const IcpResult result = RegisterPointToPlane(source, model, SE3(), IcpOptions());
  EXPECT_TRUE(result.degenerate);
  EXPECT_FALSE(result.converged);
  EXPECT_NE(result.message.find("degenerate"), std::string::npos) << result.message;
}

// A corridor leaves translation along its axis unconstrained.
TEST(RegisterPointToPlane, CorridorIsDegenerate) {
  const PointSet target = test::SampleCorridor(10.0, 4000, 0.002, test::Rng());
  const PointSet source = test::SampleCorridor(10.0, 4000, 0.002, test::Rng());
  const KdTreeTarget model(target, NormalOptions());
  const IcpResult result = RegisterPointToPlane(source, model, SE3(), IcpOptions());
  EXPECT_TRUE(result.degenerate) << result.scaled_eigenvalues.transpose();
  EXPECT_FALSE(result.converged);
  // The weakest direction is the axis translation v_x.
  const Eigen::SelfAdjointEigenSolver<Mat6> eig(result.hessian);
  EXPECT_GT(std::abs(eig.eigenvectors().col(0)(3)), 0.9) << eig.eigenvectors().col(0).transpose();
}

TEST(RegisterPointToPlane, BadInputsThrow) {
  const PointSet room = test::SampleBoxRoom(kRoom, 500, 0.0, test::Rng());
  const KdTreeTarget model(room, NormalOptions());
  const IcpOptions options;
  EXPECT_THROW(RegisterPointToPlane(PointSet{}, model, SE3(), options), InputError);
  EXPECT_THROW(RegisterPointToPlane(PointSet(room.begin(), room.begin() + 3), model, SE3(), options),
               InputError);
  PointSet with_nan = room;
  with_nan[10].x() = std::nanf("");
  EXPECT_THROW(RegisterPointToPlane(with_nan, model, SE3(), options), InputError);
  EXPECT_THROW(KdTreeTarget(with_nan, NormalOptions()), InputError);
  EXPECT_THROW(KdTreeTarget(PointSet{}, NormalOptions()), InputError);
  // Normals that do not match the points.
  EXPECT_THROW(RegisterPointToPlane(room, model, SE3(), options,
                                    std::vector<Eigen::Vector3f>(room.size() - 1)),
               InputError);
  EXPECT_THROW(KdTreeTarget(room, std::vector<Eigen::Vector3f>(5)), InputError);
  // Vertex map of the wrong size, bad intrinsics.
  const PinholeIntrinsics K{100, 100, 20, 15, 40, 30};
  EXPECT_THROW(ProjectiveTarget(PointSet(100), K), InputError);
  EXPECT_THROW(ProjectiveTarget(PointSet(1200), PinholeIntrinsics{0, 100, 20, 15, 40, 30}),
               InputError);
  // Bad options are programming errors.
  IcpOptions bad;
  bad.max_iterations = 0;
  EXPECT_THROW(RegisterPointToPlane(room, model, SE3(), bad), InternalError);
  bad = IcpOptions();
  bad.coarse_min_points = 0;
  EXPECT_THROW(RegisterPointToPlane(room, model, SE3(), bad), InternalError);
  bad = IcpOptions();
  bad.coarse_levels = -1;
  EXPECT_THROW(RegisterPointToPlane(room, model, SE3(), bad), InternalError);
  EXPECT_THROW(RobustKernelFromString("tukey"), UsageError);
}

// Monte Carlo check of the closed forms on a well-conditioned room: over 40
// noise realisations the spread of the estimates must match the closed form's
// predicted standard deviations within a factor of 2 per axis (40 samples give
// the empirical std to ~+-25 %; a 2x margin also covers the normal-noise
// correlation that the closed form ignores), for both closed forms.
TEST(ClosedFormCovariance, MatchesMonteCarloSpread) {
  const PointSet target = test::SampleBoxRoom(kRoom, 1500, 0.01, test::Rng());
  const KdTreeTarget model(target, NormalOptions{20, 1.0});
  const SE3 truth(so3::Exp(Vec3(0.01, 0.02, -0.01)), Vec3(0.05, 0.0, -0.03));
  std::vector<Vec6> errors;
  Mat6 predicted = Mat6::Zero(), predicted_censi = Mat6::Zero();
  const int runs = 40;
  for (int k = 0; k < runs; ++k) {
    const PointSet source =
        test::Transformed(test::SampleBoxRoom(kRoom, 1500, 0.01, test::Rng()), truth.Inverse());
    const IcpResult r = RegisterPointToPlane(source, model, SE3(), IcpOptions());
    ASSERT_TRUE(r.converged) << r.message;
    errors.push_back((r.target_from_source.Inverse() * truth).Log());
    predicted += ClosedFormCovariance(r) / runs;
    predicted_censi += CensiCovariance(r) / runs;
  }
  Vec6 mean = Vec6::Zero();
  for (const auto& e : errors) mean += e / runs;
  Vec6 var = Vec6::Zero();
  for (const auto& e : errors) var += (e - mean).cwiseAbs2() / (runs - 1);
  for (int i = 0; i < 6; ++i) {
    const double ratio = std::sqrt(var(i) / predicted(i, i));
    const double ratio_censi = std::sqrt(var(i) / predicted_censi(i, i));
    EXPECT_GT(ratio, 0.5) << "axis " << i;
    EXPECT_LT(ratio, 2.0) << "axis " << i;
    EXPECT_GT(ratio_censi, 0.5) << "axis " << i;
    EXPECT_LT(ratio_censi, 2.0) << "axis " << i;
  }
}

}  // namespace
}  // namespace lisfm
