// Range checks of options structs, in the style of COLMAP's CHECK_OPTION_*
// macros:
//
//   bool IcpOptions::Check() const {
//     CHECK_OPTION_GE(max_iterations, 1);
//     CHECK_OPTION_GT(max_correspondence_distance_m, 0.0);
//     CHECK_OPTION_NESTED(sgld);
//     return true;
//   }
//
// Contract: a failed check makes the enclosing function return false and
// records the failure (field address, field name, value, requirement) for the
// calling thread; LastOptionCheckFailure() returns it until the next failure.
// Nothing is printed (one debug log line): the caller that knows the user's
// context turns the record into one error line (OptionManager::ThrowUnlessValid
// names the CLI option bound to the field; THROW_CHECK_OPTIONS throws an
// InternalError naming the field). Floating-point values must also be finite:
// NaN and +-inf fail every comparison.
#pragma once

#include <cmath>
#include <sstream>
#include <string>
#include <type_traits>
#include <vector>

#include "core/errors.h"

namespace lisfm {

struct OptionCheckFailure {
  const void* field =
      nullptr;       // address of the failing field (or of the struct's member)
  std::string name;  // field name; nested fields as "map.voxel_size"
  std::string value;        // the value, formatted ("0", "-0.5", "[1, 5]")
  std::string requirement;  // what it must be (">= 1", "in (0, 2)", "<
                            // num_iterations (100)")
  // "name = value (must be requirement)".
  std::string ToString() const;
};

// The failure recorded by the last failed check on this thread (empty before
// any).
const OptionCheckFailure& LastOptionCheckFailure();

namespace internal {

void RecordOptionCheckFailure(const void* field,
                              const std::string& name,
                              const std::string& value,
                              const std::string& requirement);
// Prepends "<prefix>." to the recorded field name (CHECK_OPTION_NESTED).
void PrefixOptionCheckFailure(const std::string& prefix);

std::string FormatOptionNumber(double value);

template <typename T>
std::string FormatOptionValue(const T& value) {
  if constexpr (std::is_same_v<T, bool>) {
    return value ? "1" : "0";
  } else if constexpr (std::is_floating_point_v<T>) {
    return FormatOptionNumber(static_cast<double>(value));
  } else if constexpr (std::is_arithmetic_v<T>) {
    return std::to_string(value);
  } else if constexpr (std::is_enum_v<T>) {
    return std::to_string(static_cast<long long>(value));
  } else {
    std::ostringstream s;
    s << value;
    return s.str();
  }
}

template <typename T>
std::string FormatOptionValue(const std::vector<T>& values) {
  std::string s = "[";
  for (size_t i = 0; i < values.size(); ++i)
    s += (i ? ", " : "") + FormatOptionValue(values[i]);
  return s + "]";
}

template <typename T>
bool IsFiniteOptionValue(const T& value) {
  if constexpr (std::is_floating_point_v<T>) {
    return std::isfinite(value);
  } else {
    return true;
  }
}

// The bound as written when it is a literal ("1", "0.5"), else "name (value)".
template <typename T>
std::string FormatOptionBound(const T& bound, const char* text) {
  const std::string value = FormatOptionValue(bound);
  const char c = text[0];
  const bool literal =
      (c >= '0' && c <= '9') || c == '-' || c == '+' || c == '.';
  return literal ? value : std::string(text) + " (" + value + ")";
}

template <typename T, typename B>
bool CheckOptionOp(bool ok,
                   const T& value,
                   const void* field,
                   const char* name,
                   const char* op,
                   const B& bound,
                   const char* bound_text) {
  if (ok && IsFiniteOptionValue(value)) return true;
  RecordOptionCheckFailure(
      field,
      name,
      FormatOptionValue(value),
      std::string(op) + " " + FormatOptionBound(bound, bound_text));
  return false;
}

template <typename T>
bool CheckOption(bool ok,
                 const T& value,
                 const void* field,
                 const char* name,
                 const std::string& requirement) {
  if (ok && IsFiniteOptionValue(value)) return true;
  RecordOptionCheckFailure(field, name, FormatOptionValue(value), requirement);
  return false;
}

}  // namespace internal
}  // namespace lisfm

// `field op bound` must hold (and a floating-point field must be finite).
#define CHECK_OPTION_OP(field, op, bound)                     \
  do {                                                        \
    if (!::lisfm::internal::CheckOptionOp(((field)op(bound)), \
                                          (field),            \
                                          &(field),           \
                                          #field,             \
                                          #op,                \
                                          (bound),            \
                                          #bound)) {          \
      return false;                                           \
    }                                                         \
  } while (0)
#define CHECK_OPTION_EQ(field, bound) CHECK_OPTION_OP(field, ==, bound)
#define CHECK_OPTION_NE(field, bound) CHECK_OPTION_OP(field, !=, bound)
#define CHECK_OPTION_LE(field, bound) CHECK_OPTION_OP(field, <=, bound)
#define CHECK_OPTION_LT(field, bound) CHECK_OPTION_OP(field, <, bound)
#define CHECK_OPTION_GE(field, bound) CHECK_OPTION_OP(field, >=, bound)
#define CHECK_OPTION_GT(field, bound) CHECK_OPTION_OP(field, >, bound)

// `cond` must hold for `field`; `requirement` says what the field must be
// ("in (0, 2)", "-1 or >= 1", "one of huber, cauchy").
#define CHECK_OPTION_MSG(field, cond, requirement)               \
  do {                                                           \
    if (!::lisfm::internal::CheckOption(static_cast<bool>(cond), \
                                        (field),                 \
                                        &(field),                \
                                        #field,                  \
                                        (requirement))) {        \
      return false;                                              \
    }                                                            \
  } while (0)

// A nested options struct must pass its own Check(); its failure is reported
// as "<nested>.<field>".
#define CHECK_OPTION_NESTED(nested)                         \
  do {                                                      \
    if (!(nested).Check()) {                                \
      ::lisfm::internal::PrefixOptionCheckFailure(#nested); \
      return false;                                         \
    }                                                       \
  } while (0)

// Library entry points: invalid options are a caller bug (InternalError naming
// the failing field, its value and the requirement).
#define THROW_CHECK_OPTIONS(options)         \
  THROW_CHECK_MSG((options).Check(),         \
                  ": invalid " #options ": " \
                      << ::lisfm::LastOptionCheckFailure().ToString())
