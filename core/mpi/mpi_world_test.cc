// core/mpi: the cost-balanced split, the single-process work lists, the exact
// byte encoding of results, and the collectives under `mpirun -np 2` and
// `--oversubscribe -np 3` (mpi_world_probe; skipped with a message without
// mpirun). The commands under mpirun are in tests/e2e/mpi_test.cc.
#include "core/mpi/mpi_world.h"

#include <gtest/gtest.h>
#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <random>
#include <sstream>
#include <string>

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

TEST(RunSharedWorkList, WithoutMpiRunsEveryItemHereInOrder) {
  ASSERT_FALSE(mpi::Active());
  const std::vector<std::string> results =
      mpi::RunSharedWorkList({3, 1, 2}, [](const std::vector<size_t>& items) {
        std::vector<std::string> out;
        for (size_t i : items) out.push_back(std::to_string(10 * i));
        return out;
      });
  EXPECT_EQ(results, (std::vector<std::string>{"0", "10", "20"}));
  EXPECT_THROW(mpi::RunSharedWorkList({1},
                                      [](const std::vector<size_t>&) -> std::vector<std::string> {
                                        throw InputError("f.pcd", "", "corrupt");
                                      }),
               InputError);
}

TEST(ByteEncoding, VarintsRoundTripAndUseFewBytesForSmallValues) {
  const std::vector<uint64_t> values = {
      0, 1, 127, 128, 300, 16383, 16384, (uint64_t{1} << 32) + 5, ~uint64_t{0}};
  ByteWriter writer;
  for (uint64_t v : values) writer.PutVarint(v);
  const std::string bytes = writer.Take();
  // 1 + 1 + 1 + 2 + 2 + 2 + 3 + 5 + 10 bytes (7 bits each).
  EXPECT_EQ(bytes.size(), 27u);
  ByteReader reader(bytes);
  for (uint64_t v : values) EXPECT_EQ(reader.GetVarint(), v);
  EXPECT_TRUE(reader.AtEnd());
  // A value cut off after a continuation byte is a broken invariant.
  const std::string cut = "\x80";
  ByteReader cut_reader(cut);
  EXPECT_THROW(cut_reader.GetVarint(), InternalError);
}

// Runs `command`, returns its exit code and its standard output in *out.
int RunShell(const std::string& command, std::string* out) {
  out->clear();
  FILE* pipe = popen((command + " 2>&1").c_str(), "r");
  if (pipe == nullptr) return -1;
  std::array<char, 4096> buffer;
  size_t n;
  while ((n = fread(buffer.data(), 1, buffer.size(), pipe)) > 0) out->append(buffer.data(), n);
  const int status = pclose(pipe);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

// The probe's lines "rank R: <what>" starting with `what_prefix`, by rank.
std::map<int, std::string> RankLines(const std::string& out, const std::string& what_prefix) {
  std::map<int, std::string> lines;
  std::istringstream in(out);
  std::string line;
  while (std::getline(in, line)) {
    int rank = -1;
    char rest[4096];
    if (std::sscanf(line.c_str(), "rank %d: %4095[^\n]", &rank, rest) != 2) continue;
    if (std::string(rest).rfind(what_prefix, 0) == 0) lines[rank] = rest;
  }
  return lines;
}

class MpiCollectivesTest : public ::testing::Test {
 protected:
  void SetUp() override {
    setenv("OMPI_ALLOW_RUN_AS_ROOT", "1", 1);
    setenv("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1", 1);
    // Under AddressSanitizer (scripts/test.sh --sanitize) the ranks unwind allocation
    // stacks fully: Open MPI's libraries have no frame pointers, and the leak
    // suppressions of its allocations match frames below the first.
    if (const char* asan = std::getenv("ASAN_OPTIONS"); asan != nullptr &&
        std::string(asan).find("fast_unwind_on_malloc") == std::string::npos) {
      setenv("ASAN_OPTIONS", (std::string(asan) + ":fast_unwind_on_malloc=0").c_str(), 1);
    }
    std::string out;
    if (RunShell("mpirun --version", &out) != 0) {
      GTEST_SKIP() << "mpirun not found (apt install openmpi-bin)";
    }
  }
  static std::string Mpirun(int ranks) {
    return "mpirun --oversubscribe --bind-to none -np " + std::to_string(ranks) + " " +
           LISFM_MPI_PROBE;
  }
};

// Every rank gets every result of the shared list, in list order; a work
// list after it gathers on rank 0 only.
TEST_F(MpiCollectivesTest, SharedWorkListGivesEveryRankEveryResult) {
  for (int ranks : {2, 3}) {
    std::string out;
    ASSERT_EQ(RunShell(Mpirun(ranks) + " shared", &out), 0) << out;
    const auto shared = RankLines(out, "shared ");
    ASSERT_EQ(shared.size(), static_cast<size_t>(ranks)) << out;
    for (const auto& [rank, line] : shared) {
      EXPECT_EQ(line, "shared 0,1,4,9,16,25,36,49,64,81") << ranks << " ranks, rank " << rank;
    }
    const auto gathered = RankLines(out, "gathered ");
    ASSERT_EQ(gathered.size(), 1u) << out;
    EXPECT_EQ(gathered.begin()->first, 0);
    EXPECT_EQ(gathered.begin()->second, "gathered 0,2,8,18,32,50,72,98,128,162");
    EXPECT_EQ(RankLines(out, "released").size(), static_cast<size_t>(ranks - 1)) << out;
  }
}

// A failing item: every rank throws the same error, naming the rank that
// failed, and the run exits non-zero.
TEST_F(MpiCollectivesTest, SharedWorkListFailureReachesEveryRank) {
  for (int ranks : {2, 3}) {
    std::string out;
    EXPECT_NE(RunShell(Mpirun(ranks) + " fail", &out), 0) << out;
    const auto errors = RankLines(out, "error ");
    ASSERT_EQ(errors.size(), static_cast<size_t>(ranks)) << out;
    // Item 7 of costs {5, 1, 1, 1, 1, 1, 1, 1, 3, 1} lies on the last rank.
    const std::string expected =
        "(MPI rank " + std::to_string(ranks - 1) + " of " + std::to_string(ranks) + ")";
    for (const auto& [rank, line] : errors) {
      EXPECT_NE(line.find("bad.pcd"), std::string::npos) << line;
      EXPECT_NE(line.find(expected), std::string::npos) << line;
    }
    EXPECT_TRUE(RankLines(out, "shared ").empty()) << out;
  }
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
