// The parts of core/mpi that do not need mpirun: the cost-balanced split, the
// single-process work list, and the exact byte encoding of results. The runs
// under mpirun are in tests/e2e/mpi_test.cc.
#include "core/mpi/mpi_world.h"

#include <gtest/gtest.h>

#include <cstring>
#include <random>

namespace lisfm {
namespace {

TEST(SplitByCost, EqualCostsGiveEqualContiguousParts) {
  EXPECT_EQ(mpi::SplitByCost(std::vector<double>(8, 1.0), 2), (std::vector<size_t>{0, 4, 8}));
  EXPECT_EQ(mpi::SplitByCost(std::vector<double>(9, 2.0), 3), (std::vector<size_t>{0, 3, 6, 9}));
  EXPECT_EQ(mpi::SplitByCost(std::vector<double>(5, 1.0), 1), (std::vector<size_t>{0, 5}));
}

TEST(SplitByCost, BalancesByCost) {
  // One heavy item (cost 6) and six of cost 1: the heavy one alone is half.
  const std::vector<double> costs = {6, 1, 1, 1, 1, 1, 1};
  EXPECT_EQ(mpi::SplitByCost(costs, 2), (std::vector<size_t>{0, 1, 7}));
}

TEST(SplitByCost, MorePartsThanItemsAndEmptyLists) {
  EXPECT_EQ(mpi::SplitByCost({1.0, 1.0}, 4), (std::vector<size_t>{0, 0, 1, 1, 2}));
  EXPECT_EQ(mpi::SplitByCost({}, 3), (std::vector<size_t>{0, 0, 0, 0}));
  // All costs 0: by count.
  EXPECT_EQ(mpi::SplitByCost({0, 0, 0, 0}, 2), (std::vector<size_t>{0, 2, 4}));
}

TEST(SplitByCost, CoversEveryItemOnceAndIsBalanced) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> cost(0.5, 2.0);
  std::vector<double> costs(1000);
  for (double& c : costs) c = cost(rng);
  double total = 0;
  for (double c : costs) total += c;
  for (int parts : {1, 2, 3, 4, 7}) {
    const std::vector<size_t> b = mpi::SplitByCost(costs, parts);
    ASSERT_EQ(b.size(), static_cast<size_t>(parts + 1));
    EXPECT_EQ(b.front(), 0u);
    EXPECT_EQ(b.back(), costs.size());
    for (int r = 0; r < parts; ++r) {
      ASSERT_LE(b[r], b[r + 1]);
      double part = 0;
      for (size_t i = b[r]; i < b[r + 1]; ++i) part += costs[i];
      // Each boundary is off its ideal by at most one item (cost <= 2).
      EXPECT_NEAR(part, total / parts, 2 * 2.0) << parts << " parts, part " << r;
    }
  }
}

TEST(RunWorkList, WithoutMpiRunsEveryItemHereInOrder) {
  ASSERT_FALSE(mpi::Active());
  EXPECT_EQ(mpi::WorldSize(), 1);
  EXPECT_EQ(mpi::WorldRank(), 0);
  const auto results = mpi::RunWorkList({1, 1, 1}, [](const std::vector<size_t>& items) {
    std::vector<std::string> out;
    for (size_t i : items) out.push_back(std::to_string(i));
    return out;
  });
  ASSERT_TRUE(results.has_value());
  EXPECT_EQ(*results, (std::vector<std::string>{"0", "1", "2"}));
  // A failing item: the error reaches the caller unchanged.
  EXPECT_THROW(mpi::RunWorkList({1},
                                [](const std::vector<size_t>&) -> std::vector<std::string> {
                                  throw InputError("f.pcd", "", "corrupt");
                                }),
               InputError);
}

TEST(ByteEncoding, RoundTripsPosesAndMatricesBitForBit) {
  std::mt19937 rng(3);
  std::normal_distribution<double> normal;
  for (int k = 0; k < 100; ++k) {
    Vec6 xi;
    for (int d = 0; d < 6; ++d) xi(d) = normal(rng);
    const SE3 pose = SE3::Exp(xi) * SE3::Exp(0.3 * xi);
    Mat6 m;
    for (int d = 0; d < 36; ++d) m.data()[d] = normal(rng);
    ByteWriter writer;
    writer.Put<int32_t>(k);
    writer.PutSe3(pose);
    writer.PutMatrix(m);
    writer.PutString("pair");
    const std::string bytes = writer.Take();
    ByteReader reader(bytes);
    EXPECT_EQ(reader.Get<int32_t>(), k);
    const SE3 back = reader.GetSe3();
    const Mat6 m_back = reader.GetMatrix<Mat6>();
    EXPECT_EQ(reader.GetString(), "pair");
    EXPECT_TRUE(reader.AtEnd());
    EXPECT_EQ(
        std::memcmp(
            back.rotation().coeffs().data(), pose.rotation().coeffs().data(), 4 * sizeof(double)),
        0);
    EXPECT_EQ(std::memcmp(back.translation().data(), pose.translation().data(), 3 * sizeof(double)),
              0);
    EXPECT_EQ(std::memcmp(m_back.data(), m.data(), 36 * sizeof(double)), 0);
  }
  // Reading past the end is a broken invariant.
  const std::string short_bytes = "abc";
  ByteReader reader(short_bytes);
  EXPECT_THROW(reader.Get<int64_t>(), InternalError);
}

}  // namespace
}  // namespace lisfm
