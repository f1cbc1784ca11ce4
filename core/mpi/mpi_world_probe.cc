// A test program for mpi_world_test.cc, run under `mpirun -np N`: drives the
// collectives of core/mpi and prints what each rank got, one line per rank
// ("rank R: ..."), so that the test can compare the ranks.
//   mpi_world_probe shared   a RunSharedWorkList of 10 items (item i's result
//                            is i * i as text), then a RunWorkList over the
//                            shared results (each item's result doubled)
//   mpi_world_probe fail     a RunSharedWorkList whose item 7 throws an
//                            InputError naming "bad.pcd"
// Exit code: mpi::Finish's (1 for the failure).
#include <iostream>
#include <numeric>
#include <string>
#include <vector>

#include "core/errors.h"
#include "core/mpi/mpi_world.h"

namespace {

std::string Join(const std::vector<std::string>& values) {
  std::string out;
  for (const std::string& v : values) out += (out.empty() ? "" : ",") + v;
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  lisfm::mpi::Init(&argc, &argv);
  const std::string mode = argc > 1 ? argv[1] : "";
  const std::string me = "rank " + std::to_string(lisfm::mpi::WorldRank()) + ": ";
  // Unequal costs: the split is not by count.
  const std::vector<double> costs = {5, 1, 1, 1, 1, 1, 1, 1, 3, 1};
  int code = 0;
  bool collective = false;
  try {
    const std::vector<std::string> shared =
        lisfm::mpi::RunSharedWorkList(costs, [&](const std::vector<size_t>& items) {
          std::vector<std::string> out;
          for (size_t i : items) {
            if (mode == "fail" && i == 7) throw lisfm::InputError("bad.pcd", "", "corrupt");
            out.push_back(std::to_string(i * i));
          }
          return out;
        });
    std::cout << me + "shared " + Join(shared) + "\n" << std::flush;
    const auto gathered = lisfm::mpi::RunWorkList(costs, [&](const std::vector<size_t>& items) {
      std::vector<std::string> out;
      for (size_t i : items) out.push_back(std::to_string(2 * std::stoi(shared[i])));
      return out;
    });
    std::cout << me + (gathered ? "gathered " + Join(*gathered) : std::string("released")) + "\n"
              << std::flush;
  } catch (const lisfm::mpi::RankError& e) {
    std::cout << me + "error " + e.what() + "\n" << std::flush;
    code = e.exit_code();
    collective = true;
  }
  return lisfm::mpi::Finish(code, collective);
}
