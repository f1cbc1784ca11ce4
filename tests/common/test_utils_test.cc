#include "tests/common/test_utils.h"

#include <string>

#include <gtest/gtest.h>

#include "core/errors.h"

namespace lisfm {
namespace {

void ThrowTumError() { throw InputError("traj.txt", "line 2", "expected 8 columns, found 7"); }

TEST(ThrowsInputError, SucceedsWhenTheMessageHoldsEveryFragment) {
  EXPECT_TRUE(test::ThrowsInputError(ThrowTumError, {"traj.txt", "line 2", "found 7"}));
  EXPECT_TRUE(test::ThrowsInputError(ThrowTumError));
  EXPECT_TRUE(test::ThrowsInputError(ThrowTumError, {""}));
}

TEST(ThrowsInputError, FailsWithTheMessageAndTheMissingFragments) {
  const ::testing::AssertionResult result =
      test::ThrowsInputError(ThrowTumError, {"traj.txt", "line 3", "found 6"});
  EXPECT_FALSE(result);
  const std::string message = result.message();
  EXPECT_NE(message.find("lacks \"line 3\" \"found 6\""), std::string::npos) << message;
  EXPECT_NE(message.find("traj.txt:line 2: expected 8 columns, found 7"), std::string::npos)
      << message;
}

TEST(ThrowsInputError, FailsWhenNothingOrSomethingElseIsThrown) {
  const ::testing::AssertionResult nothing = test::ThrowsInputError([] {}, {"x"});
  EXPECT_FALSE(nothing);
  EXPECT_NE(std::string(nothing.message()).find("nothing was thrown"), std::string::npos);
  const ::testing::AssertionResult internal =
      test::ThrowsInputError([] { THROW_CHECK_EQ(1, 2); }, {"x"});
  EXPECT_FALSE(internal);
  EXPECT_NE(std::string(internal.message()).find("lisfm::InternalError"), std::string::npos)
      << internal.message();
  const ::testing::AssertionResult other = test::ThrowsInputError([] { throw 42; });
  EXPECT_FALSE(other);
  EXPECT_NE(std::string(other.message()).find("not derived from std::exception"),
            std::string::npos)
      << other.message();
}

}  // namespace
}  // namespace lisfm
