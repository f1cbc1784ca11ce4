#include "icp/projective_icp.h"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <cmath>
#include <random>

#include "core/errors.h"
#include "icp/testing/scenes.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

const Eigen::Vector3d kRoom(3.0, 2.0, 4.0);  // half sizes of the synthetic room (m)
const PinholeIntrinsics kK{150, 150, 79.5, 59.5, 160, 120};

// The depth image (z, m) of the box room seen from world_from_camera, with
// Gaussian depth noise of sigma_m.
std::vector<float> RenderDepth(const SE3& world_from_camera, double sigma_m, std::mt19937* rng) {
  const PointSet vertices = test::RenderBoxRoom(kRoom, world_from_camera, kK);
  std::normal_distribution<float> g(0.f, static_cast<float>(sigma_m));
  std::vector<float> depth(vertices.size());
  for (size_t i = 0; i < vertices.size(); ++i) {
    depth[i] = vertices[i].z() + (sigma_m > 0 ? g(*rng) : 0.f);
  }
  return depth;
}

VertexNormalMap MapOf(const std::vector<float>& depth) {
  VertexNormalMap map;
  ComputeVertexNormalMap(depth, kK, 0.1, 20.0, 0.05, &map);
  return map;
}

// Looking down (0.35 rad) into a corner, so that the floor constrains y.
const SE3 kWorldFromTarget(so3::Exp(Vec3(0.35, 0.6, 0.0)), Vec3(0.3, -0.5, -1.0));
// A motion larger than between two 30 Hz frames: 57 mm, 2.2 deg.
const SE3 kTargetFromSource(so3::Exp(Vec3(0.02, -0.03, 0.01)), Vec3(0.04, -0.03, 0.03));

// Noise-free rendered depth: point-to-plane is exact on the walls; nearest-pixel
// association pairs a few points near the room's edges with the adjacent wall,
// which leaves a bias of ~0.1 mm (as in icp_test's projective case): bounds
// 0.3 mm / 0.3 mrad against a 57 mm / 38 mrad displacement.
TEST(RegisterProjective, RecoversKnownMotionNoiseFree) {
  std::mt19937 rng(1);
  const VertexNormalMap target = MapOf(RenderDepth(kWorldFromTarget, 0.0, &rng));
  const VertexNormalMap source =
      MapOf(RenderDepth(kWorldFromTarget * kTargetFromSource, 0.0, &rng));
  const ProjectiveIcpResult result =
      RegisterProjective(source, target, kK, SE3(), ProjectiveIcpOptions());
  EXPECT_TRUE(result.converged) << result.message;
  EXPECT_FALSE(result.degenerate);
  EXPECT_GT(result.num_inliers, source.NumValid() * 8 / 10);
  EXPECT_TRUE(test::PosesNear(result.target_from_source, kTargetFromSource, 3e-4, 3e-4));
  EXPECT_LT(result.rmse_m, 1e-3);
  // The information matrix is symmetric positive definite.
  EXPECT_TRUE(result.information.isApprox(result.information.transpose(), 1e-9));
  EXPECT_GT(Eigen::SelfAdjointEigenSolver<Mat6>(result.information).eigenvalues()(0), 0.0);
}

// 3 mm depth noise on both images (a Kinect at ~1.5 m): ~15k matches average the
// noise down to well below a millimetre; the normals from central differences are
// noisy too (the Huber weights and the normal-angle gate keep that from biasing).
// Bounds 1.5 mm / 1 mrad, still far below the displacement.
TEST(RegisterProjective, RecoversKnownMotionNoisy) {
  std::mt19937 rng(7);
  const VertexNormalMap target = MapOf(RenderDepth(kWorldFromTarget, 0.003, &rng));
  const VertexNormalMap source =
      MapOf(RenderDepth(kWorldFromTarget * kTargetFromSource, 0.003, &rng));
  ProjectiveIcpOptions options;
  options.max_normal_angle_deg = 45;  // noisy normals from central differences
  const ProjectiveIcpResult result = RegisterProjective(source, target, kK, SE3(), options);
  EXPECT_TRUE(result.converged) << result.message;
  EXPECT_TRUE(test::PosesNear(result.target_from_source, kTargetFromSource, 1e-3, 1.5e-3));
}

// A_i against central differences of r(xi) = n^T (Exp(omega) p + dt - q) at xi = 0.
TEST(ProjectivePointToPlane, MatchesFiniteDifferences) {
  const Eigen::Vector3d p(0.3, -0.7, 2.1), q(0.25, -0.6, 2.0);
  const Eigen::Vector3d n = Eigen::Vector3d(0.2, -0.4, -0.9).normalized();
  Eigen::Matrix<double, 1, 6> a;
  const double b = ProjectivePointToPlane(p, q, n, &a);
  EXPECT_NEAR(b, n.dot(p - q), 1e-15);
  const auto r = [&](const Eigen::VectorXd& xi) {
    Eigen::VectorXd out(1);
    out(0) = n.dot(so3::ExpMatrix(xi.head<3>()) * p + xi.tail<3>() - q);
    return out;
  };
  const Eigen::MatrixXd numeric = test::NumericJacobian(r, Eigen::VectorXd::Zero(6));
  EXPECT_TRUE(numeric.isApprox(a, 1e-6)) << numeric << "\nvs\n" << a;
}

// The photometric row against central differences of the residual as a function
// of the pose, r(xi) = I(pi(Exp(omega) p + dt)) - I_s, in double precision. The
// image I(u, v) = c + a u + b v + d u v is reproduced exactly by bilinear
// interpolation, and so are its gradients (a + d v, b + d u) by the level's
// central-difference images: the analytic row must match to rounding.
TEST(ProjectivePhotometric, MatchesFiniteDifferences) {
  const double c0 = 0.3, ca = 0.004, cb = -0.003, cd = 2e-5;
  const auto image = [&](double u, double v) { return c0 + ca * u + cb * v + cd * u * v; };
  std::vector<float> intensity(static_cast<size_t>(kK.width) * kK.height);
  for (int v = 0; v < kK.height; ++v) {
    for (int u = 0; u < kK.width; ++u) {
      intensity[static_cast<size_t>(v) * kK.width + u] = static_cast<float>(image(u, v));
    }
  }
  IntensityPyramid::Level level;
  level.intensity = intensity;
  level.grad_u.resize(intensity.size());
  level.grad_v.resize(intensity.size());
  for (int v = 0; v < kK.height; ++v) {
    for (int u = 0; u < kK.width; ++u) {
      level.grad_u[static_cast<size_t>(v) * kK.width + u] = static_cast<float>(ca + cd * v);
      level.grad_v[static_cast<size_t>(v) * kK.width + u] = static_cast<float>(cb + cd * u);
    }
  }
  const Eigen::Vector3d p(0.3, -0.2, 2.1);
  const double source_intensity = 0.42;
  Eigen::Matrix<double, 1, 6> a;
  double r = 0;
  ASSERT_TRUE(ProjectivePhotometric(p, source_intensity, level, kK, &r, &a));
  const auto residual = [&](const Eigen::VectorXd& xi) {
    const Eigen::Vector3d x = so3::ExpMatrix(xi.head<3>()) * p + xi.tail<3>();
    Eigen::VectorXd out(1);
    out(0) = image(kK.fx * x.x() / x.z() + kK.cx, kK.fy * x.y() / x.z() + kK.cy) - source_intensity;
    return out;
  };
  EXPECT_NEAR(r, residual(Eigen::VectorXd::Zero(6))(0), 1e-6);
  const Eigen::MatrixXd numeric = test::NumericJacobian(residual, Eigen::VectorXd::Zero(6));
  EXPECT_TRUE(numeric.isApprox(a, 1e-5)) << numeric << "\nvs\n" << a;
  // Behind the camera or outside the image: no row.
  EXPECT_FALSE(ProjectivePhotometric(Eigen::Vector3d(0, 0, -1), 0.5, level, kK, &r, &a));
  EXPECT_FALSE(ProjectivePhotometric(Eigen::Vector3d(5, 0, 1), 0.5, level, kK, &r, &a));
}

// A textured wall z = 2 m (world) seen from a camera facing it: the depth image
// is the same constant from both poses, so the in-plane motion (x, y, rotation
// about the optical axis) is unobservable by depth. Texture: smooth stripes of
// 0.17-0.3 m periods (13-22 pixels at 2 m).
struct TexturedWall {
  static double Texture(double x, double y) {
    return 0.5 + 0.2 * std::sin(2 * M_PI * x / 0.3) * std::cos(2 * M_PI * y / 0.25) +
           0.1 * std::sin(2 * M_PI * (x + 0.5 * y) / 0.17);
  }
  // Depth (m) and intensity of the wall seen from world_from_camera (rotation
  // about z and translation in x, y only: every depth is 2 m).
  static void Render(const SE3& world_from_camera,
                     std::vector<float>* depth,
                     std::vector<float>* intensity) {
    const size_t n = static_cast<size_t>(kK.width) * kK.height;
    depth->assign(n, 2.0f);
    intensity->resize(n);
    for (int v = 0; v < kK.height; ++v) {
      for (int u = 0; u < kK.width; ++u) {
        const Eigen::Vector3d x_c((u - kK.cx) / kK.fx * 2.0, (v - kK.cy) / kK.fy * 2.0, 2.0);
        const Eigen::Vector3d x_w = world_from_camera * x_c;
        (*intensity)[static_cast<size_t>(v) * kK.width + u] =
            static_cast<float>(Texture(x_w.x(), x_w.y()));
      }
    }
  }
};

// Depth alone leaves the in-plane motion free (the estimate stays at the initial
// guess, 36 mm and 0.5 deg away); the hybrid term recovers it.
TEST(RegisterProjective, PhotometricTermRecoversMotionAlongTexturedWall) {
  const SE3 target_from_source(so3::Exp(Vec3(0.0, 0.0, 0.008)), Vec3(0.03, -0.02, 0.0));
  std::vector<float> depth_t, depth_s, intensity_t, intensity_s;
  TexturedWall::Render(SE3(), &depth_t, &intensity_t);
  TexturedWall::Render(target_from_source, &depth_s, &intensity_s);
  const VertexNormalMap target = MapOf(depth_t), source = MapOf(depth_s);
  ProjectiveIcpOptions options;
  IntensityPyramid pyramid_t, pyramid_s;
  BuildIntensityPyramid(intensity_t, kK.width, kK.height, options.num_levels, &pyramid_t);
  BuildIntensityPyramid(intensity_s, kK.width, kK.height, options.num_levels, &pyramid_s);

  ProjectiveIcpOptions depth_only = options;
  depth_only.photometric_weight = 0;
  const ProjectiveIcpResult geometric =
      RegisterProjective(source, target, kK, SE3(), depth_only, &pyramid_s, &pyramid_t);
  EXPECT_TRUE(geometric.degenerate);
  EXPECT_EQ(geometric.num_photometric, 0u);
  EXPECT_GT((geometric.target_from_source.translation() - target_from_source.translation()).norm(),
            0.03);

  options.max_iterations_per_level = 20;
  const ProjectiveIcpResult hybrid =
      RegisterProjective(source, target, kK, SE3(), options, &pyramid_s, &pyramid_t);
  EXPECT_FALSE(hybrid.degenerate) << hybrid.message;
  EXPECT_GT(hybrid.num_photometric, source.NumValid() * 8 / 10);
  EXPECT_TRUE(test::PosesNear(hybrid.target_from_source, target_from_source, 1e-3, 1e-3))
      << hybrid.target_from_source.translation().transpose() << " " << hybrid.message;
}

// One wall fills the image: translation along the wall is unobservable.
TEST(RegisterProjective, SingleWallIsDegenerate) {
  std::vector<float> depth(static_cast<size_t>(kK.width) * kK.height, 2.0f);
  const VertexNormalMap wall = MapOf(depth);
  const ProjectiveIcpResult result =
      RegisterProjective(wall, wall, kK, SE3(), ProjectiveIcpOptions());
  EXPECT_TRUE(result.degenerate);
  EXPECT_FALSE(result.converged);
  EXPECT_NE(result.message.find("degenerate"), std::string::npos) << result.message;
}

TEST(RegisterProjective, BadInputThrows) {
  std::mt19937 rng(1);
  const VertexNormalMap target = MapOf(RenderDepth(kWorldFromTarget, 0.0, &rng));
  VertexNormalMap truncated = target;
  truncated.normals.pop_back();
  EXPECT_THROW(RegisterProjective(truncated, target, kK, SE3(), ProjectiveIcpOptions()),
               InputError);
  PinholeIntrinsics other = kK;
  other.width = 80;
  EXPECT_THROW(RegisterProjective(target, target, other, SE3(), ProjectiveIcpOptions()),
               InputError);
  ProjectiveIcpOptions bad;
  bad.num_levels = 0;
  EXPECT_THROW(RegisterProjective(target, target, kK, SE3(), bad), InternalError);
}

// Normals from central differences on a wall facing the camera point back at it.
TEST(ComputeVertexNormalMap, WallAndDiscontinuity) {
  std::vector<float> depth(static_cast<size_t>(kK.width) * kK.height, 2.0f);
  for (int v = 0; v < kK.height; ++v) {
    for (int u = kK.width / 2; u < kK.width; ++u) depth[v * kK.width + u] = 3.0f;  // a step
  }
  depth[10 * kK.width + 10] = 0.f;  // a hole
  const VertexNormalMap map = MapOf(depth);
  const size_t centre = 60 * kK.width + 40;
  ASSERT_TRUE(map.Valid(centre));
  EXPECT_TRUE(map.normals[centre].isApprox(Eigen::Vector3f(0, 0, -1), 1e-5f));
  EXPECT_NEAR(map.vertices[centre].x(), (40 - kK.cx) / kK.fx * 2.0, 1e-6);
  EXPECT_FALSE(map.Valid(10 * kK.width + 10));            // no depth
  EXPECT_FALSE(map.Valid(10 * kK.width + 11));            // a neighbour has none
  EXPECT_FALSE(map.Valid(60 * kK.width + kK.width / 2));  // at the step
  EXPECT_FALSE(map.Valid(0));                             // border
}

// A wider normal window: exact on a noise-free plane, no normals within r pixels
// of a depth step, and on a noisy plane (3 mm at 2 m, 1.3 cm pixels) a normal
// scatter ~ 1 / sqrt(2 sum k^2) of the depth noise: r = 2 less than half of
// central differences' (r = 1).
TEST(ComputeVertexNormalMap, WiderWindowSmoothsNormals) {
  const size_t n = static_cast<size_t>(kK.width) * kK.height;
  std::vector<float> depth(n, 2.0f);
  for (int v = 0; v < kK.height; ++v) {
    for (int u = kK.width / 2; u < kK.width; ++u) depth[v * kK.width + u] = 3.0f;  // a step
  }
  VertexNormalMap map;
  ComputeVertexNormalMap(depth, kK, 0.1, 20.0, 0.05, &map, 2);
  ASSERT_TRUE(map.Valid(60 * kK.width + 40));
  EXPECT_TRUE(map.normals[60 * kK.width + 40].isApprox(Eigen::Vector3f(0, 0, -1), 1e-5f));
  EXPECT_TRUE(map.Valid(60 * kK.width + kK.width / 2 - 3));
  EXPECT_FALSE(map.Valid(60 * kK.width + kK.width / 2 - 2));  // 2 pixels from the step
  EXPECT_FALSE(map.Valid(1 * kK.width + 40));                 // within 2 of the border

  std::mt19937 rng(3);
  std::normal_distribution<float> noise(0.f, 0.003f);
  for (float& z : depth) z = 2.0f + noise(rng);
  const auto mean_angle = [&](int window) {
    ComputeVertexNormalMap(depth, kK, 0.1, 20.0, 0.05, &map, window);
    double sum = 0;
    size_t count = 0;
    for (size_t i = 0; i < n; ++i) {
      if (!map.Valid(i)) continue;
      sum += std::acos(std::min(1.0f, -map.normals[i].z()));
      ++count;
    }
    EXPECT_GT(count, n / 2);
    return sum / count;
  };
  const double central = mean_angle(1), wide = mean_angle(2);
  EXPECT_GT(central, 0.1);  // central differences: ~0.2 rad of scatter
  EXPECT_LT(wide, 0.5 * central);
}

// Crease rejection: a frontal wall (z = 2 m) meeting a wall at 45 deg along column
// 80. Noise-free, every normal kept is its own wall's (window 2); without the
// rejection the pixels whose window spans the crease mix the two. On a noisy plane
// (3 mm at 2 m) the rejection keeps almost every pixel.
TEST(ComputeVertexNormalMap, CreaseRejection) {
  const size_t n = static_cast<size_t>(kK.width) * kK.height;
  const double x_crease = (80 - kK.cx) / kK.fx * 2.0;
  std::vector<float> depth(n);
  for (int v = 0; v < kK.height; ++v) {
    for (int u = 0; u < kK.width; ++u) {
      // Wall B: z - x = 2 - x_crease, with x = a z, a = (u - cx) / fx.
      const double a = (u - kK.cx) / kK.fx;
      depth[v * kK.width + u] = static_cast<float>(u <= 80 ? 2.0 : (2.0 - x_crease) / (1.0 - a));
    }
  }
  const Eigen::Vector3f n_a(0, 0, -1), n_b = Eigen::Vector3f(1, 0, -1).normalized();
  const auto worst_angle = [&](const VertexNormalMap& map, size_t* valid) {
    double worst = 0;
    *valid = 0;
    for (int v = 0; v < kK.height; ++v) {
      for (int u = 0; u < kK.width; ++u) {
        const size_t i = static_cast<size_t>(v) * kK.width + u;
        if (!map.Valid(i)) continue;
        ++*valid;
        const float c = map.normals[i].dot(u <= 80 ? n_a : n_b);
        worst = std::max(worst, std::acos(std::min(1.0, static_cast<double>(c))));
      }
    }
    return worst;
  };
  VertexNormalMap map;
  size_t valid = 0;
  ComputeVertexNormalMap(depth, kK, 0.1, 20.0, 0.05, &map, 2, 3.0);
  EXPECT_LT(worst_angle(map, &valid), 1e-3);
  const size_t interior = static_cast<size_t>(kK.width - 4) * (kK.height - 4);
  EXPECT_GT(valid, interior - 8 * static_cast<size_t>(kK.height));  // a few columns at the crease
  ComputeVertexNormalMap(depth, kK, 0.1, 20.0, 0.05, &map, 2, 0.0);
  EXPECT_GT(worst_angle(map, &valid), 0.1);  // mixed normals at the crease

  std::mt19937 rng(5);
  std::normal_distribution<float> noise(0.f, 0.003f);
  for (float& z : depth) z = 2.0f + noise(rng);
  ComputeVertexNormalMap(depth, kK, 0.1, 20.0, 0.05, &map, 2, 3.0);
  EXPECT_GT(map.NumValid(), interior * 97 / 100);
}

}  // namespace
}  // namespace lisfm
