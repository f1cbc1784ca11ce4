// Table-driven tests of an options struct's Check(): each case sets one field
// out of its range, and Check() must fail naming exactly that field
// (LastOptionCheckFailure(), core/option_check.h). Header for tests only.
#pragma once

#include <gtest/gtest.h>

#include <functional>
#include <string>
#include <vector>

#include "core/option_check.h"

namespace lisfm {
namespace test {

template <typename Options>
struct BadOption {
  std::string
      field;  // as the failure names it ("map.voxel_size" for nested fields)
  std::function<void(Options*)> set;
};

// `valid` must pass Check(); every case applied to a copy of it must fail on
// its field.
template <typename Options>
void ExpectCheckRejects(const std::vector<BadOption<Options>>& cases,
                        const Options& valid = Options()) {
  ASSERT_TRUE(valid.Check()) << LastOptionCheckFailure().ToString();
  for (const BadOption<Options>& c : cases) {
    Options o = valid;
    c.set(&o);
    EXPECT_FALSE(o.Check())
        << c.field << ": an out-of-range value passes Check()";
    EXPECT_EQ(LastOptionCheckFailure().name, c.field)
        << LastOptionCheckFailure().ToString();
  }
}

}  // namespace test
}  // namespace lisfm
