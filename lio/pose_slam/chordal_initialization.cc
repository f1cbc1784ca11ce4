#include "lio/pose_slam/chordal_initialization.h"

#include <Eigen/SVD>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <numeric>

#include "core/errors.h"

namespace lisfm {
namespace {

using Triplet = Eigen::Triplet<double>;
using SparseMatrix = Eigen::SparseMatrix<double>;

// Adds the d x d block `m` at block row `r`, block column `c`.
void AddBlock(int r, int c, const MatX& m, std::vector<Triplet>* triplets) {
  const int d = static_cast<int>(m.rows());
  for (int a = 0; a < d; ++a) {
    for (int b = 0; b < d; ++b) {
      if (m(a, b) != 0.0) triplets->emplace_back(d * r + a, d * c + b, m(a, b));
    }
  }
}

void CheckConnected(int num_poses, const std::vector<ChordalMeasurement>& measurements) {
  std::vector<int> parent(num_poses);
  std::iota(parent.begin(), parent.end(), 0);
  const auto find = [&](int a) {
    while (parent[a] != a) a = parent[a] = parent[parent[a]];
    return a;
  };
  for (const ChordalMeasurement& m : measurements) {
    THROW_CHECK_MSG(m.i >= 0 && m.i < num_poses && m.j >= 0 && m.j < num_poses && m.i != m.j,
                    "ChordalInitialization: measurement " << m.i << " -> " << m.j << " with "
                                                          << num_poses << " poses");
    parent[find(m.i)] = find(m.j);
  }
  for (int k = 1; k < num_poses; ++k) {
    THROW_CHECK_MSG(find(k) == find(0),
                    "ChordalInitialization: pose " << k << " is not connected to pose 0");
  }
}

MatX Solve(int size, const std::vector<Triplet>& triplets, const MatX& rhs) {
  SparseMatrix A(size, size);
  A.setFromTriplets(triplets.begin(), triplets.end());
  const Eigen::SimplicialLDLT<SparseMatrix> ldlt(A);
  THROW_CHECK_MSG(ldlt.info() == Eigen::Success,
                  "ChordalInitialization: the linear system is singular");
  return ldlt.solve(rhs);
}

MatX NearestRotation(const MatX& m) {
  const Eigen::JacobiSVD<MatX> svd(m, Eigen::ComputeFullU | Eigen::ComputeFullV);
  MatX s = MatX::Identity(m.rows(), m.cols());
  s(m.rows() - 1, m.cols() - 1) = (svd.matrixU() * svd.matrixV().transpose()).determinant();
  return svd.matrixU() * s * svd.matrixV().transpose();
}

}  // namespace

double ChordalObjective(const std::vector<ChordalMeasurement>& measurements,
                        const std::vector<SE3>& world_from_pose) {
  double sum = 0.0;
  for (const ChordalMeasurement& m : measurements) {
    const SE3& a = world_from_pose.at(m.i);
    const SE3& b = world_from_pose.at(m.j);
    const Mat3 Ra = a.RotationMatrix();
    sum +=
        m.kappa * (b.RotationMatrix() - Ra * m.i_from_j.RotationMatrix()).squaredNorm() +
        m.tau * (b.translation() - a.translation() - Ra * m.i_from_j.translation()).squaredNorm();
  }
  return sum;
}

std::vector<SE3> ChordalInitialization(int dimension,
                                       int num_poses,
                                       const std::vector<ChordalMeasurement>& measurements) {
  THROW_CHECK_MSG(dimension == 2 || dimension == 3,
                  "ChordalInitialization: dimension " << dimension);
  THROW_CHECK_GE(num_poses, 1);
  CheckConnected(num_poses, measurements);
  const int d = dimension;
  const int n = num_poses - 1;  // unknown poses 1..num_poses-1 -> rows 0..n-1
  std::vector<SE3> poses(num_poses);
  if (n == 0) return poses;

  // 1. Rotations. Row r of R_k as the column x_k^(r); R_j = R_i R~ row by row
  // is x_j^(r) = M x_i^(r) with M = R~^T, the same system for every r: the
  // unknown block of pose k is X_k = [x_k^(0) ... x_k^(d-1)] = R_k^T, pose 0's
  // is I (right-hand side).
  std::vector<Triplet> triplets;
  MatX rhs = MatX::Zero(d * n, d);
  const MatX I = MatX::Identity(d, d);
  for (const ChordalMeasurement& m : measurements) {
    const MatX M = m.i_from_j.RotationMatrix().topLeftCorner(d, d).transpose();
    const int i = m.i - 1, j = m.j - 1;
    if (i >= 0) AddBlock(i, i, m.kappa * I, &triplets);  // M^T M = I
    if (j >= 0) AddBlock(j, j, m.kappa * I, &triplets);
    if (i >= 0 && j >= 0) {
      AddBlock(i, j, -m.kappa * M.transpose(), &triplets);
      AddBlock(j, i, -m.kappa * M, &triplets);
    } else if (i < 0) {
      rhs.middleRows(d * j, d) += m.kappa * M;
    } else {
      rhs.middleRows(d * i, d) += m.kappa * M.transpose();
    }
  }
  const MatX X = Solve(d * n, triplets, rhs);
  std::vector<Mat3> rotations(num_poses, Mat3::Identity());
  for (int k = 0; k < n; ++k) {
    rotations[k + 1].topLeftCorner(d, d) = NearestRotation(X.middleRows(d * k, d).transpose());
  }

  // 2. Translations: the tau-weighted graph Laplacian, t_0 = 0.
  triplets.clear();
  MatX rhs_t = MatX::Zero(n, d);
  for (const ChordalMeasurement& m : measurements) {
    const Eigen::RowVectorXd c = (rotations[m.i] * m.i_from_j.translation()).head(d).transpose();
    const int i = m.i - 1, j = m.j - 1;
    if (i >= 0) {
      triplets.emplace_back(i, i, m.tau);
      rhs_t.row(i) -= m.tau * c;
    }
    if (j >= 0) {
      triplets.emplace_back(j, j, m.tau);
      rhs_t.row(j) += m.tau * c;
    }
    if (i >= 0 && j >= 0) {
      triplets.emplace_back(i, j, -m.tau);
      triplets.emplace_back(j, i, -m.tau);
    }
  }
  const MatX t = Solve(n, triplets, rhs_t);
  for (int k = 0; k < n; ++k) {
    Vec3 translation = Vec3::Zero();
    translation.head(d) = t.row(k).transpose();
    poses[k + 1] = SE3(rotations[k + 1], translation);
  }
  return poses;
}

}  // namespace lisfm
