#include "icp/projective_icp.h"

#include <fmt/format.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <cmath>

#include "core/errors.h"
#include "core/option_check.h"

namespace lisfm {

namespace {

constexpr double kDegToRad = M_PI / 180.0;

// Sums of one image row: the upper triangle of sum w A^T A (21), sum w A^T b (6),
// sum w b^2, sum b^2, count, and the inlier points' sum and squared norms (for L).
struct RowSums {
  std::array<double, 21> h{};
  std::array<double, 6> g{};
  double weighted_sq = 0, sq = 0;
  Eigen::Vector3d point_sum = Eigen::Vector3d::Zero();
  double point_sq = 0;
  size_t count = 0;
  size_t photometric_count = 0;
  void Clear() { *this = RowSums(); }
  void Add(const RowSums& o) {
    for (int i = 0; i < 21; ++i) h[i] += o.h[i];
    for (int i = 0; i < 6; ++i) g[i] += o.g[i];
    weighted_sq += o.weighted_sq;
    sq += o.sq;
    point_sum += o.point_sum;
    point_sq += o.point_sq;
    count += o.count;
    photometric_count += o.photometric_count;
  }
  // Adds the row w a^T a, w a^T b of one residual to h and g.
  void AddRow(const Eigen::Matrix<double, 1, 6>& a, double b, double w) {
    int k = 0;
    for (int x = 0; x < 6; ++x) {
      const double wa = w * a(x);
      for (int y = x; y < 6; ++y) h[k++] += wa * a(y);
      g[x] += wa * b;
    }
  }
};

// 1D Gaussian blur of sigma (pixels) along rows (step 1) or columns (step width),
// clamped at the border.
void BlurAxis(const std::vector<float>& in,
              int width,
              int height,
              bool along_rows,
              const std::vector<float>& kernel,
              std::vector<float>* out) {
  const int r = static_cast<int>(kernel.size()) / 2;
  out->resize(in.size());
  tbb::parallel_for(0, height, [&](int v) {
    for (int u = 0; u < width; ++u) {
      float sum = 0.f;
      for (int k = -r; k <= r; ++k) {
        const int uu = along_rows ? std::clamp(u + k, 0, width - 1) : u;
        const int vv = along_rows ? v : std::clamp(v + k, 0, height - 1);
        sum += kernel[k + r] * in[static_cast<size_t>(vv) * width + uu];
      }
      (*out)[static_cast<size_t>(v) * width + u] = sum;
    }
  });
}

// Bilinear sample of a level's intensity and gradients at (u, v) (pixels); false
// outside [0, width - 1) x [0, height - 1).
bool Sample(const IntensityPyramid::Level& level,
            int width,
            int height,
            float u,
            float v,
            float* intensity,
            float* grad_u,
            float* grad_v) {
  if (!(u >= 0.f && v >= 0.f && u < width - 1 && v < height - 1)) return false;
  const int u0 = static_cast<int>(u), v0 = static_cast<int>(v);
  const float a = u - u0, b = v - v0;
  const size_t i = static_cast<size_t>(v0) * width + u0;
  const float w00 = (1 - a) * (1 - b), w10 = a * (1 - b), w01 = (1 - a) * b, w11 = a * b;
  auto lerp = [&](const std::vector<float>& img) {
    return w00 * img[i] + w10 * img[i + 1] + w01 * img[i + width] + w11 * img[i + width + 1];
  };
  *intensity = lerp(level.intensity);
  *grad_u = lerp(level.grad_u);
  *grad_v = lerp(level.grad_v);
  return true;
}

// Planarity score of each pixel with a normal n (0 elsewhere): the largest
// off-plane second difference over the window, max_{k=1..r, axis} |n . (x(-k) +
// x(+k) - 2 x)| / z^2 (1/m). A plane meets the rays of an image row (column) in a
// line, so on a plane the score is zero up to depth noise, whose sigma grows ~z^2
// for structured-light and time-of-flight sensors; a crease (two planes) within
// the window makes it grow with the pixel footprint. Pixels whose score exceeds
// sigma times the frame's clipped RMS score (5 rounds of clipping at that
// threshold, in pixel order) lose their normal; the threshold is at least 1e-6 /m
// (1 um at 1 m, float rounding of noise-free depth).
void RejectCreases(double sigma, int r, VertexNormalMap* map) {
  const int w = map->width, h = map->height;
  std::vector<float> score(map->normals.size(), 0.f);
  tbb::parallel_for(0, h, [&](int v) {
    for (int u = 0; u < w; ++u) {
      const size_t i = static_cast<size_t>(v) * w + u;
      if (!map->Valid(i)) continue;
      const Eigen::Vector3f& n = map->normals[i];
      const Eigen::Vector3f x2 = 2.f * map->vertices[i];
      float dev = 0.f;
      for (int k = 1; k <= r; ++k) {
        const size_t step_v = static_cast<size_t>(k) * w;
        dev = std::max(dev, std::abs(n.dot(map->vertices[i - k] + map->vertices[i + k] - x2)));
        dev = std::max(dev,
                       std::abs(n.dot(map->vertices[i - step_v] + map->vertices[i + step_v] - x2)));
      }
      const float z = map->vertices[i].z();
      score[i] = dev / (z * z);
    }
  });
  double threshold = std::numeric_limits<double>::infinity();
  for (int round = 0; round < 5; ++round) {
    double sum_sq = 0;
    size_t count = 0;
    for (size_t i = 0; i < score.size(); ++i) {
      if (!map->Valid(i) || score[i] > threshold) continue;
      sum_sq += static_cast<double>(score[i]) * score[i];
      ++count;
    }
    if (count == 0) return;
    threshold = std::max(sigma * std::sqrt(sum_sq / count), 1e-6);
  }
  const float limit = static_cast<float>(threshold);
  tbb::parallel_for(size_t{0}, score.size(), [&](size_t i) {
    if (score[i] > limit) map->normals[i].setZero();
  });
}

void CheckMap(const VertexNormalMap& map, const char* what) {
  const size_t n = static_cast<size_t>(std::max(map.width, 0)) * std::max(map.height, 0);
  if (map.width <= 0 || map.height <= 0 || map.vertices.size() != n || map.normals.size() != n) {
    throw InputError(what,
                     "",
                     fmt::format("expected {}x{} = {} vertices and normals, found {} and {}",
                                 map.width,
                                 map.height,
                                 n,
                                 map.vertices.size(),
                                 map.normals.size()));
  }
}

}  // namespace

void VertexNormalMap::Resize(int w, int h) {
  width = w;
  height = h;
  const size_t n = static_cast<size_t>(w) * static_cast<size_t>(h);
  vertices.resize(n);
  normals.resize(n);
}

size_t VertexNormalMap::NumValid() const {
  size_t n = 0;
  for (size_t i = 0; i < normals.size(); ++i) n += Valid(i) ? 1 : 0;
  return n;
}

void ComputeVertexNormalMap(const std::vector<float>& depth_m,
                            const PinholeIntrinsics& K,
                            double min_depth_m,
                            double max_depth_m,
                            double max_depth_jump,
                            VertexNormalMap* out,
                            int normal_window_px,
                            double crease_rejection_sigma) {
  const int w = K.width, h = K.height;
  THROW_CHECK_EQ(depth_m.size(), static_cast<size_t>(w) * static_cast<size_t>(h));
  THROW_CHECK(max_depth_jump > 0);
  THROW_CHECK(normal_window_px >= 1);
  THROW_CHECK(crease_rejection_sigma >= 0);
  out->Resize(w, h);
  const float zmin = static_cast<float>(min_depth_m), zmax = static_cast<float>(max_depth_m);
  const float fx_inv = static_cast<float>(1.0 / K.fx), fy_inv = static_cast<float>(1.0 / K.fy);
  const float cx = static_cast<float>(K.cx), cy = static_cast<float>(K.cy);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  tbb::parallel_for(0, h, [&](int v) {
    for (int u = 0; u < w; ++u) {
      const size_t i = static_cast<size_t>(v) * w + u;
      const float z = depth_m[i];
      out->vertices[i] = (z >= zmin && z <= zmax && std::isfinite(z))
                             ? Eigen::Vector3f((u - cx) * fx_inv * z, (v - cy) * fy_inv * z, z)
                             : Eigen::Vector3f(nan, nan, 0.f);
    }
  });
  const float jump = static_cast<float>(max_depth_jump);
  const int r = normal_window_px;
  tbb::parallel_for(0, h, [&](int v) {
    for (int u = 0; u < w; ++u) {
      const size_t i = static_cast<size_t>(v) * w + u;
      Eigen::Vector3f& n = out->normals[i];
      n.setZero();
      if (u < r || v < r || u + r >= w || v + r >= h) continue;
      const float z = out->vertices[i].z();
      if (!(z > 0)) continue;
      const float limit = jump * z;
      bool ok = true;
      Eigen::Vector3f du = Eigen::Vector3f::Zero(), dv = Eigen::Vector3f::Zero();
      for (int k = 1; k <= r && ok; ++k) {
        const size_t step_v = static_cast<size_t>(k) * w;
        const Eigen::Vector3f& l = out->vertices[i - k];
        const Eigen::Vector3f& rt = out->vertices[i + k];
        const Eigen::Vector3f& up = out->vertices[i - step_v];
        const Eigen::Vector3f& dn = out->vertices[i + step_v];
        const float reach = k * limit;
        for (const Eigen::Vector3f* x : {&l, &rt, &up, &dn}) {
          ok = ok && x->z() > 0 && std::abs(x->z() - z) <= reach;
        }
        du += static_cast<float>(k) * (rt - l);
        dv += static_cast<float>(k) * (dn - up);
      }
      if (!ok) continue;
      Eigen::Vector3f c = du.cross(dv);
      const float norm = c.norm();
      if (!(norm > 0)) continue;
      c /= norm;
      if (c.dot(out->vertices[i]) > 0) c = -c;
      n = c;
    }
  });
  if (crease_rejection_sigma > 0) RejectCreases(crease_rejection_sigma, r, out);
}

bool ProjectiveIcpOptions::Check() const {
  CHECK_OPTION_MSG(num_levels, num_levels >= 1 && num_levels <= 5, "in [1, 5]");
  CHECK_OPTION_GE(max_iterations_per_level, 1);
  CHECK_OPTION_GT(max_correspondence_distance_m, 0.0);
  CHECK_OPTION_MSG(
      max_normal_angle_deg, max_normal_angle_deg > 0 && max_normal_angle_deg <= 180, "in (0, 180]");
  CHECK_OPTION_GE(huber_threshold_m, 0.0);
  CHECK_OPTION_GE(convergence_rotation_rad, 0.0);
  CHECK_OPTION_GE(convergence_translation_m, 0.0);
  CHECK_OPTION_GE(min_inliers, 6);
  CHECK_OPTION_GE(degeneracy_threshold, 0.0);
  CHECK_OPTION_GE(photometric_weight, 0.0);
  CHECK_OPTION_GE(photometric_huber, 0.0);
  return true;
}

double ProjectivePointToPlane(const Eigen::Vector3d& p,
                              const Eigen::Vector3d& q,
                              const Eigen::Vector3d& n,
                              Eigen::Matrix<double, 1, 6>* a) {
  // n^T (-[p]x omega) = n . (omega x p) = omega . (p x n).
  a->leftCols<3>() = p.cross(n).transpose();
  a->rightCols<3>() = n.transpose();
  return n.dot(p - q);
}

void BuildIntensityPyramid(const std::vector<float>& intensity,
                           int width,
                           int height,
                           int num_levels,
                           IntensityPyramid* out) {
  THROW_CHECK(width >= 3 && height >= 3 && num_levels >= 1);
  THROW_CHECK_EQ(intensity.size(), static_cast<size_t>(width) * static_cast<size_t>(height));
  out->width = width;
  out->height = height;
  out->levels.resize(static_cast<size_t>(num_levels));
  std::vector<float> tmp;
  for (int l = 0; l < num_levels; ++l) {
    IntensityPyramid::Level& level = out->levels[l];
    // Gaussian kernel of sigma 0.75 * 2^l, radius ceil(2.5 sigma), normalised.
    const double sigma = 0.75 * (1 << l);
    const int r = static_cast<int>(std::ceil(2.5 * sigma));
    std::vector<float> kernel(static_cast<size_t>(2 * r + 1));
    float sum = 0.f;
    for (int k = -r; k <= r; ++k) {
      kernel[k + r] = static_cast<float>(std::exp(-0.5 * k * k / (sigma * sigma)));
      sum += kernel[k + r];
    }
    for (float& k : kernel) k /= sum;
    BlurAxis(intensity, width, height, true, kernel, &tmp);
    BlurAxis(tmp, width, height, false, kernel, &level.intensity);
    // Central differences, one-sided at the border: dI/du, dI/dv per pixel.
    level.grad_u.resize(intensity.size());
    level.grad_v.resize(intensity.size());
    const std::vector<float>& img = level.intensity;
    tbb::parallel_for(0, height, [&](int v) {
      for (int u = 0; u < width; ++u) {
        const size_t i = static_cast<size_t>(v) * width + u;
        const int ul = std::max(u - 1, 0), ur = std::min(u + 1, width - 1);
        const int vu = std::max(v - 1, 0), vd = std::min(v + 1, height - 1);
        level.grad_u[i] =
            (img[static_cast<size_t>(v) * width + ur] - img[static_cast<size_t>(v) * width + ul]) /
            static_cast<float>(ur - ul);
        level.grad_v[i] =
            (img[static_cast<size_t>(vd) * width + u] - img[static_cast<size_t>(vu) * width + u]) /
            static_cast<float>(vd - vu);
      }
    });
  }
}

bool ProjectivePhotometric(const Eigen::Vector3d& p,
                           double source_intensity,
                           const IntensityPyramid::Level& level,
                           const PinholeIntrinsics& K,
                           double* residual,
                           Eigen::Matrix<double, 1, 6>* a) {
  if (!(p.z() > 0)) return false;
  const double inv_z = 1.0 / p.z();
  const double u = K.fx * p.x() * inv_z + K.cx, v = K.fy * p.y() * inv_z + K.cy;
  float i_t, gu, gv;
  if (!Sample(
          level, K.width, K.height, static_cast<float>(u), static_cast<float>(v), &i_t, &gu, &gv))
    return false;
  // g = dI/dp = [gu gv] d(u, v)/dp, d(u, v)/dp = [fx/z 0 -fx x/z^2; 0 fy/z -fy y/z^2].
  const double gx = gu * K.fx * inv_z, gy = gv * K.fy * inv_z;
  const Eigen::Vector3d g(gx, gy, -(gx * p.x() + gy * p.y()) * inv_z);
  *residual = i_t - source_intensity;
  a->leftCols<3>() = p.cross(g).transpose();
  a->rightCols<3>() = g.transpose();
  return true;
}

ProjectiveIcpResult RegisterProjective(const VertexNormalMap& source,
                                       const VertexNormalMap& target,
                                       const PinholeIntrinsics& K,
                                       const SE3& initial_target_from_source,
                                       const ProjectiveIcpOptions& options,
                                       const IntensityPyramid* source_intensity,
                                       const IntensityPyramid* target_intensity) {
  THROW_CHECK_OPTIONS(options);
  CheckMap(source, "source vertex map");
  CheckMap(target, "target vertex map");
  if (!(K.fx > 0 && K.fy > 0) || K.width != target.width || K.height != target.height) {
    throw InputError("target intrinsics",
                     "",
                     fmt::format("expected fx, fy > 0 and {}x{} pixels, found fx={} fy={} {}x{}",
                                 target.width,
                                 target.height,
                                 K.fx,
                                 K.fy,
                                 K.width,
                                 K.height));
  }
  const bool photometric = options.photometric_weight > 0 && source_intensity != nullptr &&
                           target_intensity != nullptr && !source_intensity->empty() &&
                           !target_intensity->empty();
  if (photometric) {
    const auto check = [&](const IntensityPyramid& pyramid,
                           const VertexNormalMap& map,
                           const char* what) {
      if (pyramid.width != map.width || pyramid.height != map.height ||
          pyramid.levels.size() < static_cast<size_t>(options.num_levels)) {
        throw InputError(what,
                         "",
                         fmt::format("expected a {}x{} intensity pyramid of at least {} levels, "
                                     "found {}x{} with {}",
                                     map.width,
                                     map.height,
                                     options.num_levels,
                                     pyramid.width,
                                     pyramid.height,
                                     pyramid.levels.size()));
      }
    };
    check(*source_intensity, source, "source intensity");
    check(*target_intensity, target, "target intensity");
  }
  const double photo_weight = options.photometric_weight;
  const double photo_huber = options.photometric_huber;
  const float min_cos = static_cast<float>(std::cos(options.max_normal_angle_deg * kDegToRad));
  const double huber = options.huber_threshold_m;
  const float fx = static_cast<float>(K.fx), fy = static_cast<float>(K.fy);
  const float cx = static_cast<float>(K.cx), cy = static_cast<float>(K.cy);
  const int tw = target.width, th = target.height;

  std::vector<RowSums> rows(static_cast<size_t>(source.height));
  SE3 T = initial_target_from_source;
  ProjectiveIcpResult result;
  RowSums total;
  Mat6 last_h = Mat6::Zero();
  bool small_step = false;

  for (int level = options.num_levels - 1; level >= 0; --level) {
    const int stride = 1 << level;
    const int num_rows = (source.height + stride - 1) / stride;
    const double max_distance_m = options.max_correspondence_distance_m * stride;
    const float max_sq = static_cast<float>(max_distance_m * max_distance_m);
    small_step = false;
    for (int it = 0; it < options.max_iterations_per_level; ++it) {
      const Eigen::Matrix3f R = T.RotationMatrix().cast<float>();
      const Eigen::Vector3f t = T.translation().cast<float>();
      tbb::parallel_for(
          tbb::blocked_range<int>(0, num_rows, 8), [&](const tbb::blocked_range<int>& r) {
            Eigen::Matrix<double, 1, 6> a, a_photo;
            for (int row = r.begin(); row != r.end(); ++row) {
              RowSums& s = rows[row];
              s.Clear();
              const int v = row * stride;
              for (int u = 0; u < source.width; u += stride) {
                const size_t i = static_cast<size_t>(v) * source.width + u;
                if (!source.Valid(i)) continue;
                const Eigen::Vector3f p = R * source.vertices[i] + t;
                if (!(p.z() > 0)) continue;
                // Nearest pixel: floor(x + 0.5), range-checked before the cast.
                const float inv_z = 1.f / p.z();
                const float uf = fx * p.x() * inv_z + cx + 0.5f,
                            vf = fy * p.y() * inv_z + cy + 0.5f;
                if (!(uf >= 0.f && vf >= 0.f && uf < tw && vf < th)) continue;
                const int tu = static_cast<int>(uf), tv = static_cast<int>(vf);
                const size_t j = static_cast<size_t>(tv) * tw + tu;
                if (!target.Valid(j)) continue;
                const Eigen::Vector3f& q = target.vertices[j];
                if ((p - q).squaredNorm() >= max_sq) continue;
                const Eigen::Vector3f& n = target.normals[j];
                if ((R * source.normals[i]).dot(n) < min_cos) continue;
                const Eigen::Vector3d pd = p.cast<double>();
                const double b = ProjectivePointToPlane(pd, q.cast<double>(), n.cast<double>(), &a);
                const double ab = std::abs(b);
                const double w = (huber > 0 && ab > huber) ? huber / ab : 1.0;
                s.AddRow(a, b, w);
                if (photometric) {
                  double r_photo;
                  if (ProjectivePhotometric(pd,
                                            source_intensity->levels[level].intensity[i],
                                            target_intensity->levels[level],
                                            K,
                                            &r_photo,
                                            &a_photo)) {
                    const double ar = std::abs(r_photo);
                    const double wp =
                        photo_weight *
                        ((photo_huber > 0 && ar > photo_huber) ? photo_huber / ar : 1.0);
                    s.AddRow(a_photo, r_photo, wp);
                    ++s.photometric_count;
                  }
                }
                s.weighted_sq += w * b * b;
                s.sq += b * b;
                s.point_sum += pd;
                s.point_sq += pd.squaredNorm();
                ++s.count;
              }
            }
          });
      total.Clear();
      for (int row = 0; row < num_rows; ++row) total.Add(rows[row]);
      ++result.iterations;
      if (total.count < static_cast<size_t>(options.min_inliers)) break;
      Mat6 H;
      Vec6 g;
      int k = 0;
      for (int x = 0; x < 6; ++x) {
        for (int y = x; y < 6; ++y) H(x, y) = H(y, x) = total.h[k++];
        g(x) = total.g[x];
      }
      // Directions the matches do not constrain (a corridor's axis, a wall's plane):
      // eigenvalues of the scaled Hessian D H D (D = diag(1/L I3, I3), L the RMS
      // range of the matches) below a tenth of degeneracy_threshold times the
      // largest. There the step is zero, so the initial guess (the caller's motion
      // prediction) is kept (solution remapping, Zhang et al. 2016); elsewhere the
      // step is the Cholesky solution of the normal equations.
      const double range_m = std::sqrt(std::max(total.point_sq / total.count, 1e-12));
      Vec6 d;
      d << Eigen::Vector3d::Constant(1.0 / range_m), Eigen::Vector3d::Ones();
      const Eigen::SelfAdjointEigenSolver<Mat6> eig(d.asDiagonal() * H * d.asDiagonal());
      const double min_eig = 0.1 * options.degeneracy_threshold * eig.eigenvalues()(5);
      Vec6 xi;
      if (eig.eigenvalues()(0) >= min_eig && eig.eigenvalues()(0) > 0) {
        // Tiny Levenberg damping (1e-9 of the mean diagonal) against rounding.
        Mat6 damped = H;
        damped.diagonal().array() += 1e-9 * H.trace() / 6.0 + 1e-12;
        xi = -damped.llt().solve(g);
      } else {
        const Vec6 rhs = eig.eigenvectors().transpose() * (-(d.asDiagonal() * g));
        Vec6 scaled_step = Vec6::Zero();
        for (int e = 0; e < 6; ++e) {
          if (eig.eigenvalues()(e) >= min_eig && eig.eigenvalues()(e) > 0) {
            scaled_step += eig.eigenvectors().col(e) * (rhs(e) / eig.eigenvalues()(e));
          }
        }
        xi = d.asDiagonal() * scaled_step;
      }
      if (!xi.allFinite()) break;
      T = SE3(so3::Exp(xi.head<3>()), xi.tail<3>()) * T;
      last_h = H;
      small_step = xi.head<3>().norm() < options.convergence_rotation_rad &&
                   xi.tail<3>().norm() < options.convergence_translation_m;
      if (small_step) break;
    }
  }
  result.target_from_source = T;
  result.num_inliers = total.count;
  result.num_photometric = total.photometric_count;
  double length_m = 1.0;
  if (total.count > 0) {
    result.rmse_m = std::sqrt(total.sq / total.count);
    const Eigen::Vector3d mean = total.point_sum / total.count;
    length_m = std::sqrt(std::max(total.point_sq / total.count - mean.squaredNorm(), 1e-12));
  }
  // Right perturbation: T Exp(xi_r) = Exp(Ad(T) xi_r) T, so J = A Ad(T) and
  // H_right = Ad^T H_left Ad.
  const Mat6 adjoint = T.Adjoint();
  const Mat6 h_right = adjoint.transpose() * last_h * adjoint;
  const double sigma2 =
      total.count > 6 ? std::max(total.weighted_sq / (total.count - 6.0), 1e-12) : 1.0;
  result.information = h_right / sigma2;
  // Degeneracy as in RegisterPointToPlane: rotation columns scale with distance,
  // so compare eigenvalues of D H D, D = diag(1/L I3, I3); the translation block
  // (normals' spread) against the threshold, the scaled 6x6 against a tenth of it.
  Vec6 d;
  d << Eigen::Vector3d::Constant(1.0 / length_m), Eigen::Vector3d::Ones();
  const Mat6 scaled = d.asDiagonal() * h_right * d.asDiagonal();
  result.scaled_eigenvalues = Eigen::SelfAdjointEigenSolver<Mat6>(scaled).eigenvalues();
  const double max_eig = result.scaled_eigenvalues(5);
  const Eigen::Vector3d trans_eig =
      Eigen::SelfAdjointEigenSolver<Mat3>(h_right.bottomRightCorner<3, 3>()).eigenvalues();
  const double trans_ratio = trans_eig(2) > 0 ? trans_eig(0) / trans_eig(2) : 0.0;
  const double full_ratio = max_eig > 0 ? result.scaled_eigenvalues(0) / max_eig : 0.0;
  result.degenerate = !(max_eig > 0) || trans_ratio < options.degeneracy_threshold ||
                      full_ratio < 0.1 * options.degeneracy_threshold;
  const bool enough = total.count >= static_cast<size_t>(options.min_inliers);
  if (!enough) {
    result.message = fmt::format(
        "too few correspondences: {} < min_inliers {}", total.count, options.min_inliers);
  } else if (result.degenerate) {
    result.message = fmt::format(
        "degenerate geometry: Hessian eigenvalue ratios {:.2e} (translation) / {:.2e} (scaled, "
        "all) below {:.1e} / {:.1e}",
        trans_ratio,
        full_ratio,
        options.degeneracy_threshold,
        0.1 * options.degeneracy_threshold);
  } else if (!small_step) {
    result.message = fmt::format("no convergence within {} iterations at the finest level",
                                 options.max_iterations_per_level);
  } else {
    result.message = "converged";
  }
  result.converged = small_step && enough && !result.degenerate;
  return result;
}

}  // namespace lisfm
