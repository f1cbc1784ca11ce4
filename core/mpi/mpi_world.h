// The processes of one run under `mpirun -np N` (Open MPI, MPI_COMM_WORLD):
// who they are, how a work list is split among them, and how their results and
// failures reach rank 0. A process that no launcher started (no
// OMPI_COMM_WORLD_SIZE, PMI_SIZE or PMIX_RANK in its environment) never calls
// MPI_Init and behaves as one process of size 1, rank 0.
//
// Protocol of a command that distributes a work list (RunWorkList; a
// RunSharedWorkList before it follows steps 1-3 with every rank getting every
// result in step 4, so that a further split stage can use them):
//  1. every rank reads the same inputs and builds the same list;
//  2. each rank runs its share (SplitByCost) and sends the encoded results to
//     rank 0; a rank whose share throws sends the error instead;
//  3. rank 0 sends every rank the outcome: all succeeded, or the error of the
//     lowest failing rank, which every rank then throws as RankError (main
//     prints it once, on rank 0, and every rank exits with its exit code);
//  4. on success rank 0 gets all results in list order and goes on alone
//     (solve, write outputs atomically); the other ranks stop, write nothing
//     and, in Finish(), wait for rank 0's exit code and exit with it.
// Any other failure of a rank (outside its share) is printed by that rank,
// which then ends the whole run with MPI_Abort (non-zero exit everywhere); the
// outputs are only ever committed by rank 0 after step 3.
// Waiting ranks sleep between polls (1 ms) instead of spinning, so that an
// oversubscribed run leaves the cores to the ranks that work.
// Threads: call everything from the main thread only.
#pragma once

#include <cstddef>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/work_list.h"

namespace lisfm::mpi {

// True when a launcher (mpirun / mpiexec) started this process.
bool StartedByLauncher();

// MPI_Init when StartedByLauncher(), else nothing. Once, first thing in main.
void Init(int* argc, char*** argv);

bool Active();    // MPI_Init was called
int WorldSize();  // 1 without MPI
int WorldRank();  // 0 without MPI
inline bool IsRoot() { return WorldRank() == 0; }

// Splits items with costs `costs` (>= 0) into `num_parts` contiguous ranges,
// balanced by cost: returns num_parts + 1 bounds, part r = [bounds[r],
// bounds[r + 1]). Item i goes to part floor(num_parts * m_i / total) (at most
// num_parts - 1) where m_i is the cost before item i plus half its own (all
// costs 0: count each as 1). Depends only on `costs` and `num_parts`.
std::vector<size_t> SplitByCost(const std::vector<double>& costs, int num_parts);

// A WorkListRunner (core/work_list.h) over all processes: without MPI it runs
// every item here; with MPI it follows the protocol above. Throws RankError
// (on every rank) when a rank's share threw.
std::optional<std::vector<std::string>> RunWorkList(const std::vector<double>& costs,
                                                    const WorkItemsFunction& run);

// A SharedWorkListRunner (core/work_list.h) over all processes: each rank runs
// its share (SplitByCost) and every rank gets every result, in list order
// (MPI_Allgatherv of the encoded results; no rank stops, nothing is released).
// When a share throws, every rank throws the RankError of the lowest failing
// rank. Without MPI runs every item here.
std::vector<std::string> RunSharedWorkList(const std::vector<double>& costs,
                                           const WorkItemsFunction& run);

// The error of the rank whose share failed, thrown on every rank. Its message
// is that rank's message; exit_code() is 2 for a UsageError, else 1.
class RankError : public std::runtime_error {
 public:
  RankError(const std::string& message, int exit_code)
      : std::runtime_error(message), exit_code_(exit_code) {}
  int exit_code() const { return exit_code_; }

 private:
  int exit_code_;
};

// End of main with this process's exit code (after its error, if any, was
// printed). `collective_error`: the code comes from a RankError (every rank
// knows it). Returns the code to exit with; calls MPI_Finalize, or MPI_Abort
// when a rank failed outside the protocol. Without MPI returns exit_code.
int Finish(int exit_code, bool collective_error);

}  // namespace lisfm::mpi
