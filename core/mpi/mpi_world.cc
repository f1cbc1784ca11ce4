#include "core/mpi/mpi_world.h"

#include <fmt/format.h>
#include <mpi.h>

#include <algorithm>
#include <chrono>
#include <climits>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <numeric>
#include <thread>

#include "core/errors.h"

namespace lisfm::mpi {
namespace {

bool g_active = false;
int g_size = 1;
int g_rank = 0;
// A RunWorkList completed here: rank 0 then holds every result and the other
// ranks stop and wait for rank 0's exit code in Finish().
bool g_released = false;

// Waits for a non-blocking operation, sleeping between polls.
void Wait(MPI_Request* request) {
  int done = 0;
  for (;;) {
    MPI_Test(request, &done, MPI_STATUS_IGNORE);
    if (done) return;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
}

void Check(int status, const char* what) {
  if (status != MPI_SUCCESS) throw std::runtime_error(std::string("MPI: ") + what + " failed");
}

// Broadcasts rank 0's int64 values to every rank.
void BroadcastInts(int64_t* values, int count) {
  MPI_Request request;
  Check(MPI_Ibcast(values, count, MPI_INT64_T, 0, MPI_COMM_WORLD, &request), "MPI_Ibcast");
  Wait(&request);
}

int ExchangeExitCode(int exit_code) {
  int64_t root_code = exit_code;
  BroadcastInts(&root_code, 1);
  return exit_code != 0 ? exit_code : static_cast<int>(root_code);
}

// Every item here (no MPI): the results as `run` returned them.
std::vector<std::string> RunAllHere(size_t n, const WorkItemsFunction& run) {
  std::vector<size_t> all(n);
  std::iota(all.begin(), all.end(), size_t(0));
  std::vector<std::string> results = run(all);
  THROW_CHECK_EQ(results.size(), n);
  return results;
}

// Runs this rank's part [bounds[rank], bounds[rank + 1]) and returns its
// message: [int64 code][the results, each as a PutString, or the error
// message]; code 0 = success, 2 = UsageError, 1 = any other exception.
std::string RunShare(const std::vector<size_t>& bounds, const WorkItemsFunction& run) {
  std::vector<size_t> mine;
  for (size_t i = bounds[g_rank]; i < bounds[g_rank + 1]; ++i) mine.push_back(i);
  int64_t code = 0;
  std::string payload;
  try {
    const std::vector<std::string> results = run(mine);
    THROW_CHECK_EQ(results.size(), mine.size());
    ByteWriter writer;
    for (const std::string& r : results) writer.PutString(r);
    payload = writer.Take();
  } catch (const UsageError& e) {
    code = 2;
    payload = e.what();
  } catch (const std::exception& e) {
    code = 1;
    payload = e.what();
  }
  ByteWriter head;
  head.Put<int64_t>(code);
  std::string message = head.Take() + payload;
  THROW_CHECK_LT(message.size(), static_cast<size_t>(INT_MAX));
  return message;
}

// Displacements of the ranks' messages of `sizes` bytes, plus the total at the
// end (sizes.size() + 1 values).
std::vector<int> Offsets(const std::vector<int>& sizes) {
  std::vector<int> offsets(sizes.size() + 1, 0);
  int64_t total = 0;
  for (size_t r = 0; r < sizes.size(); ++r) {
    offsets[r] = static_cast<int>(total);
    total += sizes[r];
    THROW_CHECK_LT(total, static_cast<int64_t>(INT_MAX));
  }
  offsets.back() = static_cast<int>(total);
  return offsets;
}

// The code of the lowest rank whose message in `all` holds an error (0: none),
// and its message naming the rank in *error.
int64_t FirstError(const std::string& all,
                   const std::vector<int>& sizes,
                   const std::vector<int>& offsets,
                   std::string* error) {
  for (int r = 0; r < g_size; ++r) {
    const std::string part = all.substr(offsets[r], sizes[r]);
    ByteReader reader(part);
    const int64_t code = reader.Get<int64_t>();
    if (code != 0) {
      *error = part.substr(sizeof(int64_t));
      if (g_size > 1) *error += fmt::format(" (MPI rank {} of {})", r, g_size);
      return code;
    }
  }
  return 0;
}

// Every item's result, in list order, from the ranks' successful messages.
std::vector<std::string> Results(const std::string& all,
                                 const std::vector<size_t>& bounds,
                                 const std::vector<int>& sizes,
                                 const std::vector<int>& offsets) {
  std::vector<std::string> results;
  results.reserve(bounds.back());
  for (int r = 0; r < g_size; ++r) {
    const std::string part = all.substr(offsets[r], sizes[r]);
    ByteReader reader(part);
    reader.Get<int64_t>();
    for (size_t i = bounds[r]; i < bounds[r + 1]; ++i) results.push_back(reader.GetString());
    THROW_CHECK(reader.AtEnd());
  }
  return results;
}

}  // namespace

bool StartedByLauncher() {
  for (const char* name : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_RANK"}) {
    if (std::getenv(name) != nullptr) return true;
  }
  return false;
}

void Init(int* argc, char*** argv) {
  if (g_active || !StartedByLauncher()) return;
  int provided = 0;
  // Only the main thread calls MPI (TBB workers never do).
  MPI_Init_thread(argc, argv, MPI_THREAD_FUNNELED, &provided);
  g_active = true;
  MPI_Comm_size(MPI_COMM_WORLD, &g_size);
  MPI_Comm_rank(MPI_COMM_WORLD, &g_rank);
}

bool Active() { return g_active; }
int WorldSize() { return g_size; }
int WorldRank() { return g_rank; }

std::vector<size_t> SplitByCost(const std::vector<double>& costs, int num_parts) {
  THROW_CHECK_GE(num_parts, 1);
  const size_t n = costs.size();
  double total = 0.0;
  for (double c : costs) {
    THROW_CHECK_MSG(c >= 0.0 && std::isfinite(c), "cost " << c);
    total += c;
  }
  const bool unit = !(total > 0.0);
  if (unit) total = static_cast<double>(n);
  std::vector<size_t> bounds(num_parts + 1, n);
  bounds[0] = 0;
  double before = 0.0;
  int part = 0;
  for (size_t i = 0; i < n; ++i) {
    const double c = unit ? 1.0 : costs[i];
    const double middle = before + 0.5 * c;
    const int p = std::min(num_parts - 1, static_cast<int>(num_parts * middle / total));
    while (part < p) bounds[++part] = i;  // parts part+1..p start at item i
    before += c;
  }
  return bounds;
}

std::optional<std::vector<std::string>> RunWorkList(const std::vector<double>& costs,
                                                    const WorkItemsFunction& run) {
  const size_t n = costs.size();
  if (!g_active) return RunAllHere(n, run);
  const std::vector<size_t> bounds = SplitByCost(costs, g_size);
  std::string message = RunShare(bounds, run);

  // Gather the sizes, then the bytes, on rank 0.
  const int size = static_cast<int>(message.size());
  std::vector<int> sizes(g_rank == 0 ? g_size : 0);
  MPI_Request request;
  Check(MPI_Igather(&size, 1, MPI_INT, sizes.data(), 1, MPI_INT, 0, MPI_COMM_WORLD, &request),
        "MPI_Igather");
  Wait(&request);
  const std::vector<int> offsets = Offsets(sizes);
  std::string all(g_rank == 0 ? static_cast<size_t>(offsets.back()) : 0, '\0');
  Check(MPI_Igatherv(message.data(),
                     size,
                     MPI_CHAR,
                     all.data(),
                     sizes.data(),
                     offsets.data(),
                     MPI_CHAR,
                     0,
                     MPI_COMM_WORLD,
                     &request),
        "MPI_Igatherv");
  Wait(&request);
  message.clear();

  // Rank 0: the outcome (the lowest failing rank's error) to every rank.
  int64_t outcome[2] = {0, 0};  // code, length of the error message
  std::string error;
  if (g_rank == 0) {
    outcome[0] = FirstError(all, sizes, offsets, &error);
    outcome[1] = static_cast<int64_t>(error.size());
  }
  BroadcastInts(outcome, 2);
  if (outcome[0] != 0) {
    error.resize(static_cast<size_t>(outcome[1]));
    Check(MPI_Ibcast(
              error.data(), static_cast<int>(outcome[1]), MPI_CHAR, 0, MPI_COMM_WORLD, &request),
          "MPI_Ibcast");
    Wait(&request);
    throw RankError(error, static_cast<int>(outcome[0]));
  }
  g_released = true;
  if (g_rank != 0) return std::nullopt;
  return Results(all, bounds, sizes, offsets);
}

std::vector<std::string> RunSharedWorkList(const std::vector<double>& costs,
                                           const WorkItemsFunction& run) {
  const size_t n = costs.size();
  if (!g_active) return RunAllHere(n, run);
  const std::vector<size_t> bounds = SplitByCost(costs, g_size);
  std::string message = RunShare(bounds, run);

  // Every rank gets the sizes, then the bytes, of every rank.
  const int size = static_cast<int>(message.size());
  std::vector<int> sizes(g_size);
  MPI_Request request;
  Check(MPI_Iallgather(&size, 1, MPI_INT, sizes.data(), 1, MPI_INT, MPI_COMM_WORLD, &request),
        "MPI_Iallgather");
  Wait(&request);
  const std::vector<int> offsets = Offsets(sizes);
  std::string all(static_cast<size_t>(offsets.back()), '\0');
  Check(MPI_Iallgatherv(message.data(),
                        size,
                        MPI_CHAR,
                        all.data(),
                        sizes.data(),
                        offsets.data(),
                        MPI_CHAR,
                        MPI_COMM_WORLD,
                        &request),
        "MPI_Iallgatherv");
  Wait(&request);
  message.clear();

  // Every rank sees every outcome and throws the same error.
  std::string error;
  const int64_t code = FirstError(all, sizes, offsets, &error);
  if (code != 0) throw RankError(error, static_cast<int>(code));
  return Results(all, bounds, sizes, offsets);
}

int Finish(int exit_code, bool collective_error) {
  if (!g_active) return exit_code;
  if (collective_error || g_size == 1) {
    MPI_Finalize();
    return exit_code;
  }
  if (!g_released && exit_code != 0) {
    // Failed outside a work list: the other ranks may be inside one.
    std::cerr.flush();
    std::fflush(stderr);
    MPI_Abort(MPI_COMM_WORLD, exit_code);
  }
  const int code = ExchangeExitCode(exit_code);
  MPI_Finalize();
  return code;
}

}  // namespace lisfm::mpi
