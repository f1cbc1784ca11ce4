#include "lio/pose_slam/imu_factors.h"

#include <Eigen/Cholesky>
#include <cmath>

#include "core/errors.h"
#include "core/option_check.h"

namespace lisfm {

Eigen::MatrixXd SqrtInformation(const Eigen::MatrixXd& covariance) {
  THROW_CHECK_EQ(covariance.rows(), covariance.cols());
  const Eigen::LLT<Eigen::MatrixXd> llt(covariance);
  THROW_CHECK_MSG(llt.info() == Eigen::Success && covariance.allFinite(),
                  "covariance is not positive definite (zero noise densities?)");
  const Eigen::MatrixXd identity = Eigen::MatrixXd::Identity(covariance.rows(), covariance.cols());
  return llt.matrixL().solve(identity);
}

BiasRandomWalkFactor::BiasRandomWalkFactor(const ImuNoise& noise, double dt_s) {
  THROW_CHECK_GT(dt_s, 0.0);
  THROW_CHECK_GT(noise.gyroscope_random_walk, 0.0);
  THROW_CHECK_GT(noise.accelerometer_random_walk, 0.0);
  const double sqrt_dt = std::sqrt(dt_s);
  inverse_sigma.head<3>().setConstant(1.0 / (noise.gyroscope_random_walk * sqrt_dt));
  inverse_sigma.tail<3>().setConstant(1.0 / (noise.accelerometer_random_walk * sqrt_dt));
}

bool ZeroVelocityOptions::Check() const {
  CHECK_OPTION_GT(velocity_sigma, 0.0);
  CHECK_OPTION_GT(rotation_sigma, 0.0);
  CHECK_OPTION_GT(translation_sigma, 0.0);
  return true;
}

}  // namespace lisfm
