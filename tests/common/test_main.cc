// gtest main for every lisfm test: re-seeds the shared RNG before each test so
// that tests are deterministic and independent of their order.
#include <gtest/gtest.h>

#include "core/logging.h"
#include "tests/common/test_utils.h"

namespace {
class SeedListener : public ::testing::EmptyTestEventListener {
  void OnTestStart(const ::testing::TestInfo&) override {
    lisfm::test::Rng().seed(lisfm::test::kTestSeed);
  }
};
}  // namespace

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  ::testing::UnitTest::GetInstance()->listeners().Append(new SeedListener);
  lisfm::SetLogLevel(lisfm::LogLevel::kWarning);
  return RUN_ALL_TESTS();
}
