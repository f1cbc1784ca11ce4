#include "sim/camera_errors.h"

#include <algorithm>
#include <cmath>

#include "core/errors.h"
#include "core/option_check.h"
#include "sim/hash_random.h"

namespace lisfm {
namespace sim {
namespace {

constexpr float kStoreyCell = 3.0f;  // vertical lattice spacing, m

}  // namespace

bool CameraErrorOptions::Check() const {
  CHECK_OPTION_MSG(ae_target_median_dn, ae_target_median_dn > 0 && ae_target_median_dn < 255,
                   "in (0, 255)");
  CHECK_OPTION_GE(ae_time_constant_s, 0.0);
  CHECK_OPTION_GT(ae_rate_hz, 0.0);
  CHECK_OPTION_GT(min_exposure_ms, 0.0);
  CHECK_OPTION_GE(max_exposure_ms, min_exposure_ms);
  CHECK_OPTION_GE(max_gain, 1.0);
  CHECK_OPTION_GT(reference_exposure_ms, 0.0);
  CHECK_OPTION_GT(full_well_e, 0.0);
  CHECK_OPTION_GE(read_noise_e, 0.0);
  CHECK_OPTION_GE(light_level_ratio, 1.0);
  CHECK_OPTION_GT(light_cell_m, 0.0);
  CHECK_OPTION_MSG(light_change_amplitude,
                   light_change_amplitude >= 0 && light_change_amplitude < 1, "in [0, 1)");
  CHECK_OPTION_GT(light_change_period_s, 0.0);
  return true;
}

float LightField::Level(const Eigen::Vector3f& p) const {
  const Eigen::Vector3f g = (p - origin_).cwiseProduct(inv_cell_);
  auto axis = [](float v, int n, int* i0, float* f) {
    v = std::min(std::max(v, 0.f), static_cast<float>(n - 1));
    *i0 = std::min(static_cast<int>(v), std::max(n - 2, 0));
    *f = n > 1 ? v - static_cast<float>(*i0) : 0.f;
  };
  int ix, iy, iz;
  float fx, fy, fz;
  axis(g.x(), nx_, &ix, &fx);
  axis(g.y(), ny_, &iy, &fy);
  axis(g.z(), nz_, &iz, &fz);
  const int sx = nx_ > 1 ? 1 : 0, sy = ny_ > 1 ? nx_ : 0, sz = nz_ > 1 ? nx_ * ny_ : 0;
  const float* c = levels_.data() + (static_cast<size_t>(iz) * ny_ + iy) * nx_ + ix;
  const float c00 = c[0] + (c[sx] - c[0]) * fx;
  const float c10 = c[sy] + (c[sy + sx] - c[sy]) * fx;
  const float c01 = c[sz] + (c[sz + sx] - c[sz]) * fx;
  const float c11 = c[sz + sy] + (c[sz + sy + sx] - c[sz + sy]) * fx;
  const float c0 = c00 + (c10 - c00) * fy, c1 = c01 + (c11 - c01) * fy;
  return c0 + (c1 - c0) * fz;
}

SceneLighting::SceneLighting(const Eigen::AlignedBox3d& bounds,
                             uint32_t seed,
                             const CameraErrorOptions& options)
    : options_(options) {
  THROW_CHECK_OPTIONS(options_);
  THROW_CHECK(!bounds.isEmpty());
  cell_ = Eigen::Vector3f(static_cast<float>(options.light_cell_m),
                          static_cast<float>(options.light_cell_m), kStoreyCell);
  Eigen::Vector3i hi;
  for (int a = 0; a < 3; ++a) {
    lo_[a] = static_cast<int>(std::floor(bounds.min()[a] / cell_[a]));
    hi[a] = static_cast<int>(std::ceil(bounds.max()[a] / cell_[a]));
  }
  size_ = hi - lo_ + Eigen::Vector3i::Ones();
  const size_t n = static_cast<size_t>(size_.prod());
  base_.resize(n);
  phase_.resize(n);
  const uint64_t key = Mix64(static_cast<uint64_t>(seed) * 0x9E3779B97F4A7C15ULL + 0x4c494748ULL);
  const double log_ratio = std::log(options.light_level_ratio);
  for (int z = 0; z < size_.z(); ++z) {
    for (int y = 0; y < size_.y(); ++y) {
      for (int x = 0; x < size_.x(); ++x) {
        const size_t i = (static_cast<size_t>(z) * size_.y() + y) * size_.x() + x;
        uint64_t node = key;
        for (const int index : {x + lo_.x(), y + lo_.y(), z + lo_.z()}) {
          node = Mix64(node ^ static_cast<uint64_t>(static_cast<uint32_t>(index)));
        }
        base_[i] = static_cast<float>(std::exp(log_ratio * (HashUniform(node) - 0.5)));
        phase_[i] = static_cast<float>(2.0 * M_PI * HashUniform(Mix64(node + 1)));
      }
    }
  }
}

LightField SceneLighting::At(double t_s) const {
  LightField field;
  field.origin_ = lo_.cast<float>().cwiseProduct(cell_);
  field.inv_cell_ = cell_.cwiseInverse();
  field.nx_ = size_.x();
  field.ny_ = size_.y();
  field.nz_ = size_.z();
  field.levels_.resize(base_.size());
  const double omega = 2.0 * M_PI / options_.light_change_period_s;
  for (size_t i = 0; i < base_.size(); ++i) {
    field.levels_[i] = static_cast<float>(
        base_[i] * (1.0 + options_.light_change_amplitude * std::sin(omega * t_s + phase_[i])));
  }
  return field;
}

AutoExposure::AutoExposure(const CameraErrorOptions& options)
    : options_(options), product_(options.reference_exposure_s()) {
  THROW_CHECK_OPTIONS(options_);
}

double AutoExposure::TargetProduct(double median_radiance) const {
  const double lo = 1e-3 * options_.min_exposure_ms;
  const double hi = 1e-3 * options_.max_exposure_ms * options_.max_gain;
  if (median_radiance <= 0) return hi;
  // median DN = (256 / reference_exposure_s) * product * median radiance.
  const double product =
      options_.ae_target_median_dn * options_.reference_exposure_s() / (256.0 * median_radiance);
  return std::clamp(product, lo, hi);
}

void AutoExposure::Reset(double median_radiance) {
  product_ = options_.auto_exposure ? TargetProduct(median_radiance)
                                    : options_.reference_exposure_s();
}

void AutoExposure::Update(double median_radiance, double dt_s) {
  if (!options_.auto_exposure) return;
  // The controller sees the (saturated) median DN of the frame, so it knows
  // the scene only up to the 255 DN clip.
  const double measured = MedianDn(median_radiance);
  const double wanted =
      measured > 0 ? product_ * options_.ae_target_median_dn / measured : TargetProduct(0);
  const double alpha =
      options_.ae_time_constant_s > 0 ? 1.0 - std::exp(-dt_s / options_.ae_time_constant_s) : 1.0;
  const double lo = 1e-3 * options_.min_exposure_ms;
  const double hi = 1e-3 * options_.max_exposure_ms * options_.max_gain;
  product_ = std::clamp(std::exp(std::log(product_) + alpha * (std::log(wanted) - std::log(product_))),
                        lo, hi);
}

ExposureSetting AutoExposure::setting() const {
  ExposureSetting s;
  s.exposure_s = std::clamp(product_, 1e-3 * options_.min_exposure_ms,
                            1e-3 * options_.max_exposure_ms);
  s.gain = std::clamp(product_ / s.exposure_s, 1.0, options_.max_gain);
  return s;
}

double AutoExposure::MedianDn(double median_radiance) const {
  const ExposureSetting s = setting();
  return std::min(255.0, 256.0 / options_.reference_exposure_s() * s.exposure_s * s.gain *
                             median_radiance);
}

}  // namespace sim
}  // namespace lisfm
