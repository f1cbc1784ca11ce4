// Test helpers: temporary folders, data paths, a fixed-seed RNG, numeric
// Jacobians, pose comparisons and the input-error expectation. Header for
// tests only.
#pragma once

#include <functional>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "core/geometry.h"

namespace lisfm {
namespace test {

constexpr uint32_t kTestSeed = 42;

// A fresh folder under the system temp dir, removed with its contents on destruction.
class TempDir {
 public:
  TempDir();
  ~TempDir();
  const std::string& path() const { return path_; }
  std::string File(const std::string& name) const { return path_ + "/" + name; }

 private:
  std::string path_;
};

// ../shared/data as seen from the build (env LISFM_TEST_DATA_DIR); "" when missing.
std::string SharedDataDir();
// Path of a file under the shared data dir ("" if the data dir is missing).
std::string SharedData(const std::string& relative);
// The repository root (env LISFM_SOURCE_DIR).
std::string SourceDir();
// The lisfm executable (env LISFM_BINARY).
std::string LisfmBinary();

// Writes `contents` to `path` (plain, not atomic; for fixtures).
void WriteText(const std::string& path, const std::string& contents);

// Runs a shell command; returns its exit code and fills stdout+stderr.
int RunCommand(const std::string& command, std::string* output);

// Central-difference Jacobian of f: R^n -> R^m at x.
Eigen::MatrixXd NumericJacobian(const std::function<Eigen::VectorXd(const Eigen::VectorXd&)>& f,
                                const Eigen::VectorXd& x,
                                double step = 1e-6);

std::mt19937& Rng();  // seeded with kTestSeed at the start of every test
SE3 RandomPose(double max_angle_rad = 3.0, double max_translation = 5.0);

// Pose comparison as gtest assertions with readable output.
::testing::AssertionResult PosesNear(const SE3& a,
                                     const SE3& b,
                                     double max_angle_rad,
                                     double max_translation);

// Runs `f` and succeeds when it throws lisfm::InputError whose message
// contains every fragment (the file, the line or record, expected / found);
// empty fragments match anything. Fails with the message and the missing
// fragments, or with what was thrown instead (another exception, or nothing).
// Use as EXPECT_TRUE(test::ThrowsInputError([&] { ReadTum(path); },
//                                           {path, "line 2", "found 7"})).
::testing::AssertionResult ThrowsInputError(const std::function<void()>& f,
                                            const std::vector<std::string>& fragments = {});

}  // namespace test
}  // namespace lisfm

// Skips the current test with a clear reason when ../shared/data is missing.
#define LISFM_REQUIRE_SHARED_DATA(relative)                                            \
  do {                                                                                 \
    if (::lisfm::test::SharedData(relative).empty()) {                                 \
      GTEST_SKIP() << "../shared/data/" << (relative)                                  \
                   << " is missing (set LISFM_TEST_DATA_DIR); skipping real-data test"; \
    }                                                                                  \
  } while (0)
