// Association + linearisation of one source point, shared by the ICP solver
// and the Bayesian sampler. Internal to lisfm_icp (not a public API).
#pragma once

#include <cstdint>
#include <vector>

#include "icp/icp.h"

namespace lisfm {
namespace internal {

// Per-estimate constants, built once per iteration.
struct LinearizationContext {
  LinearizationContext(const SE3& target_from_source, const IcpOptions& options);
  SE3 target_from_source;
  Eigen::Matrix3f rotation_f;
  Eigen::Vector3f translation_f;
  MatchCriteria criteria;
  RobustKernel kernel;
  double kernel_scale_m;
};

struct LinearizedTerm {
  double residual = 0;                      // m
  double weight = 0;                        // IRLS weight
  Eigen::Matrix<double, 1, 6> jacobian;     // dr/dxi (right perturbation)
};

// Associates source point p (normal n, zero if unknown) under ctx and linearises.
// Returns false when the point has no admissible match; otherwise also returns
// the match (target point and unit normal, target frame) where asked. state:
// optional per-source-point state for IcpTarget::MatchTracked.
bool LinearizePoint(const IcpTarget& target,
                    const LinearizationContext& ctx,
                    const Eigen::Vector3f& p,
                    const Eigen::Vector3f& n,
                    LinearizedTerm* term,
                    Eigen::Vector3f* target_point = nullptr,
                    Eigen::Vector3f* target_normal = nullptr,
                    IcpTarget::MatchState* state = nullptr);

// Linearises the point-to-plane residual of source point p against a given
// match (q, unit normal nq) at ctx, without association.
void LinearizeMatch(const LinearizationContext& ctx,
                    const Eigen::Vector3f& p,
                    const Eigen::Vector3f& q,
                    const Eigen::Vector3f& nq,
                    LinearizedTerm* term);

}  // namespace internal
}  // namespace lisfm
