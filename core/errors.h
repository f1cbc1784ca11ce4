// Error types and invariant checks.
//
// Contract: bad *user input* (files, options, data) throws InputError naming the
// file and the line/record/field, with expected vs found. Broken internal
// invariants throw InternalError through the THROW_CHECK* macros. Library code
// never aborts and never prints; `main` catches std::exception, prints one
// `error: ...` line and exits 1 (input/runtime) or 2 (usage, UsageError).
#pragma once

#include <sstream>
#include <stdexcept>
#include <string>

namespace lisfm {

// Bad input data: a file, a record, a field. Exit code 1.
class InputError : public std::runtime_error {
 public:
  explicit InputError(const std::string& message);
  // "<path>:<location>: <message>", location may be "line 12", "field cam0.intrinsics", ...
  InputError(const std::string& path,
             const std::string& location,
             const std::string& message);
};

// Bad command line: unknown option, missing required option, bad value. Exit code 2.
class UsageError : public std::runtime_error {
 public:
  explicit UsageError(const std::string& message) : std::runtime_error(message) {}
};

// A broken invariant inside lisfm (a bug, not bad input). Exit code 1.
class InternalError : public std::logic_error {
 public:
  explicit InternalError(const std::string& message) : std::logic_error(message) {}
};

namespace internal {
[[noreturn]] void ThrowCheckFailure(const char* file,
                                    int line,
                                    const std::string& condition,
                                    const std::string& detail);

template <typename A, typename B>
std::string FormatOperands(const A& a, const B& b) {
  std::ostringstream s;
  s << " (" << a << " vs " << b << ")";
  return s.str();
}
}  // namespace internal

}  // namespace lisfm

#define THROW_CHECK(cond)                                                  \
  do {                                                                     \
    if (!(cond)) ::lisfm::internal::ThrowCheckFailure(__FILE__, __LINE__, #cond, ""); \
  } while (0)

#define THROW_CHECK_MSG(cond, msg)                                          \
  do {                                                                      \
    if (!(cond)) {                                                          \
      std::ostringstream lisfm_check_stream_;                               \
      lisfm_check_stream_ << msg;                                           \
      ::lisfm::internal::ThrowCheckFailure(__FILE__, __LINE__, #cond,       \
                                           lisfm_check_stream_.str());      \
    }                                                                       \
  } while (0)

#define LISFM_THROW_CHECK_OP(a, b, op)                                     \
  do {                                                                     \
    const auto& lisfm_a_ = (a);                                            \
    const auto& lisfm_b_ = (b);                                            \
    if (!(lisfm_a_ op lisfm_b_))                                           \
      ::lisfm::internal::ThrowCheckFailure(                                \
          __FILE__, __LINE__, #a " " #op " " #b,                           \
          ::lisfm::internal::FormatOperands(lisfm_a_, lisfm_b_));          \
  } while (0)

#define THROW_CHECK_EQ(a, b) LISFM_THROW_CHECK_OP(a, b, ==)
#define THROW_CHECK_NE(a, b) LISFM_THROW_CHECK_OP(a, b, !=)
#define THROW_CHECK_LT(a, b) LISFM_THROW_CHECK_OP(a, b, <)
#define THROW_CHECK_LE(a, b) LISFM_THROW_CHECK_OP(a, b, <=)
#define THROW_CHECK_GT(a, b) LISFM_THROW_CHECK_OP(a, b, >)
#define THROW_CHECK_GE(a, b) LISFM_THROW_CHECK_OP(a, b, >=)
