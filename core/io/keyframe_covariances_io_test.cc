#include "core/io/keyframe_covariances_io.h"

#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "core/errors.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

Mat6 RandomCovariance() {
  std::normal_distribution<double> normal(0.0, 1e-2);
  Mat6 a;
  for (int r = 0; r < 6; ++r) {
    for (int c = 0; c < 6; ++c) a(r, c) = normal(test::Rng());
  }
  return a * a.transpose();
}

TEST(KeyframeCovariancesIo, RoundTripIsExact) {
  std::vector<KeyframeCovariance> records(5);
  for (size_t k = 0; k < records.size(); ++k) {
    records[k].t_ns = 1650000000000000000 + 100000000LL * static_cast<int64_t>(k);
    records[k].covariance = k == 0 ? Mat6::Zero().eval() : RandomCovariance();  // gauge: zero
  }
  test::TempDir dir;
  WriteKeyframeCovariances(records, dir.File("c.txt"));
  const std::vector<KeyframeCovariance> read = ReadKeyframeCovariances(dir.File("c.txt"));
  ASSERT_EQ(read.size(), records.size());
  for (size_t k = 0; k < records.size(); ++k) {
    EXPECT_EQ(read[k].t_ns, records[k].t_ns);
    EXPECT_EQ(read[k].covariance, records[k].covariance);  // 17 digits: bit-exact
  }
}

TEST(KeyframeCovariancesIo, EmptyFile) {
  test::TempDir dir;
  test::WriteText(dir.File("c.txt"), "# only a comment\n\n");
  EXPECT_TRUE(ReadKeyframeCovariances(dir.File("c.txt")).empty());
}

TEST(KeyframeCovariancesIo, MalformedFilesNameFileAndLine) {
  const std::string entries21 = "1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 1";
  struct Case {
    std::string name;
    std::string text;
    std::string location;
    std::string message;
  };
  const std::vector<Case> cases = {
      {"field count", "# c\n100 1 2 3\n", "line 2", "found 4"},
      {"stamp", "1.5 " + entries21 + "\n", "line 1", "integer stamp"},
      {"nan", "100 nan" + entries21.substr(1) + "\n", "line 1", "finite number"},
      {"order", "200 " + entries21 + "\n100 " + entries21 + "\n", "line 2", "after 200"},
      {"negative", "100 -1" + entries21.substr(1) + "\n", "line 1", "semi-definite"},
  };
  test::TempDir dir;
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    const std::string path = dir.File("bad.txt");
    test::WriteText(path, c.text);
    EXPECT_TRUE(test::ThrowsInputError([&] { ReadKeyframeCovariances(path); },
                                       {path, c.location, c.message}));
  }
  EXPECT_TRUE(test::ThrowsInputError([&] { ReadKeyframeCovariances(dir.File("missing.txt")); },
                                     {dir.File("missing.txt")}));
}

}  // namespace
}  // namespace lisfm
