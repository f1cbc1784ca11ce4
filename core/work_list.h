// A list of independent work items that a library hands to its caller to run,
// in this process or split across processes (core/mpi/mpi_world.h), and the
// exact byte encoding of their results.
//
// Contract of a WorkListRunner: given each item's estimated cost (any
// non-negative unit; only the split uses it) and `run`, it calls `run` with
// some subset of the item indices (ascending) on each process, and returns
//  - on the process that continues (a single process, or MPI rank 0): every
//    item's result, in list order, exactly as `run` returned it;
//  - std::nullopt on a process whose results went to the continuing one: the
//    caller stops there (its share is done, it writes nothing).
// `run` must give an item the same bytes whatever other items it runs with and
// in whatever process (its result depends on the item only), so the outcome
// does not depend on the number of processes. An exception thrown by `run` on
// any process is rethrown by the runner on every process (see mpi_world.h).
// An empty runner means: run every item here, without encoding.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <functional>
#include <optional>
#include <string>
#include <type_traits>
#include <vector>

#include "core/errors.h"
#include "core/geometry.h"
#include "core/types.h"

namespace lisfm {

// Results of the items `items` (ascending indices into the list), one byte
// string per item, in the order of `items`.
using WorkItemsFunction = std::function<std::vector<std::string>(const std::vector<size_t>& items)>;

using WorkListRunner = std::function<std::optional<std::vector<std::string>>(
    const std::vector<double>& costs, const WorkItemsFunction& run)>;

// Like a WorkListRunner, but every process gets every item's result, in list
// order, and goes on (none stops): for a split stage whose results a further
// split stage needs on every process. An empty one means: run every item here.
using SharedWorkListRunner = std::function<std::vector<std::string>(
    const std::vector<double>& costs, const WorkItemsFunction& run)>;

// Appends values as their bytes (this machine's representation: every process
// of one run is the same build on the same kind of machine).
class ByteWriter {
 public:
  template <typename T>
  void Put(const T& value) {
    static_assert(std::is_trivially_copyable_v<T>, "Put() takes plain values");
    bytes_.append(reinterpret_cast<const char*>(&value), sizeof(T));
  }
  template <typename Derived>
  void PutMatrix(const Eigen::MatrixBase<Derived>& m) {
    for (Eigen::Index c = 0; c < m.cols(); ++c) {
      for (Eigen::Index r = 0; r < m.rows(); ++r) Put<double>(m(r, c));
    }
  }
  // The quaternion's coefficients and the translation, bit for bit.
  void PutSe3(const SE3& pose) {
    PutMatrix(pose.rotation().coeffs());
    PutMatrix(pose.translation());
  }
  // An unsigned value in 7-bit groups, low first, the high bit of each byte
  // set when more follow (LEB128): 1 byte below 128, 2 below 16384.
  void PutVarint(uint64_t value) {
    while (value >= 0x80) {
      bytes_.push_back(static_cast<char>((value & 0x7f) | 0x80));
      value >>= 7;
    }
    bytes_.push_back(static_cast<char>(value));
  }
  void PutString(const std::string& s) {
    Put<uint64_t>(s.size());
    bytes_ += s;
  }
  std::string Take() { return std::move(bytes_); }

 private:
  std::string bytes_;
};

// Reads what a ByteWriter wrote, in the same order; reading past the end is a
// broken invariant (InternalError).
class ByteReader {
 public:
  explicit ByteReader(const std::string& bytes) : bytes_(bytes) {}
  template <typename T>
  T Get() {
    static_assert(std::is_trivially_copyable_v<T>, "Get() returns plain values");
    THROW_CHECK_LE(offset_ + sizeof(T), bytes_.size());
    T value;
    std::memcpy(&value, bytes_.data() + offset_, sizeof(T));
    offset_ += sizeof(T);
    return value;
  }
  template <typename Matrix>
  Matrix GetMatrix() {
    Matrix m;
    for (Eigen::Index c = 0; c < m.cols(); ++c) {
      for (Eigen::Index r = 0; r < m.rows(); ++r) m(r, c) = Get<double>();
    }
    return m;
  }
  // The pose PutSe3() wrote, bit for bit: the stored quaternion is already
  // unit, so it is assigned as is (SE3's constructor would normalise it again,
  // which can move its last bit).
  SE3 GetSe3() {
    const Eigen::Vector4d coeffs = GetMatrix<Eigen::Vector4d>();
    const Vec3 translation = GetMatrix<Vec3>();
    SE3 pose;
    const_cast<Quat&>(pose.rotation()).coeffs() = coeffs;  // pose is not const
    pose.SetTranslation(translation);
    return pose;
  }
  // What PutVarint() wrote; a value running past the end or over 64 bits is
  // a broken invariant (InternalError).
  uint64_t GetVarint() {
    uint64_t value = 0;
    for (int shift = 0;; shift += 7) {
      THROW_CHECK_LT(offset_, bytes_.size());
      THROW_CHECK_LT(shift, 64);
      const auto byte = static_cast<uint8_t>(bytes_[offset_++]);
      value |= static_cast<uint64_t>(byte & 0x7f) << shift;
      if ((byte & 0x80) == 0) return value;
    }
  }
  std::string GetString() {
    const uint64_t n = Get<uint64_t>();
    THROW_CHECK_LE(offset_ + n, bytes_.size());
    std::string s = bytes_.substr(offset_, n);
    offset_ += n;
    return s;
  }
  bool AtEnd() const { return offset_ == bytes_.size(); }

 private:
  const std::string& bytes_;
  size_t offset_ = 0;
};

}  // namespace lisfm
