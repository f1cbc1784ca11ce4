// Time stamps: int64 nanoseconds everywhere in memory, CSV files and file names
// (DESIGN.md "Time"). Seconds (double) only at the TUM boundary.
#pragma once

#include <cmath>
#include <cstdint>
#include <string>

#include "core/errors.h"

namespace lisfm {

using TimestampNs = int64_t;  // nanoseconds since an arbitrary epoch (sensor clock)

constexpr int64_t kNsPerSecond = 1000000000LL;

// Seconds whose nanoseconds fit in int64 satisfy |t| < kMaxAbsSecondsAsNs
// (int64 ns span +-9223372036.85 s, ~292 years; the bound leaves room for the
// rounding of the fraction).
constexpr double kMaxAbsSecondsAsNs = 9.2233720368e9;

inline double NsToSeconds(TimestampNs t_ns) { return static_cast<double>(t_ns) * 1e-9; }

// True when SecondsToNs(t_s) is defined: finite and |t_s| < kMaxAbsSecondsAsNs.
inline bool IsRepresentableAsNs(double t_s) { return std::abs(t_s) < kMaxAbsSecondsAsNs; }

// Rounds to the nearest nanosecond. Exact for the 9 decimals TUM files carry
// up to ~1e7 s of magnitude, because the integer and fractional parts are
// split before scaling. Contract: IsRepresentableAsNs(t_s) (readers check
// their input with it); otherwise throws InternalError instead of wrapping.
inline TimestampNs SecondsToNs(double t_s) {
  THROW_CHECK_MSG(IsRepresentableAsNs(t_s), t_s << " s is outside the int64 nanosecond range");
  const double whole = std::floor(t_s);
  return static_cast<TimestampNs>(whole) * kNsPerSecond +
         static_cast<TimestampNs>(std::llround((t_s - whole) * 1e9));
}

// Parses a decimal seconds string ("1646307131.123456789") to ns without going
// through double, so 19-digit stamps keep every digit; exponent forms ("1e3")
// go through double. Returns false on bad syntax and on values outside the
// int64 nanosecond range (e.g. "1e10", "9300000000").
bool ParseSecondsToNs(const std::string& text, TimestampNs* t_ns);

// Formats ns as seconds with 9 decimals ("1646307131.123456789").
std::string FormatNsAsSeconds(TimestampNs t_ns);

}  // namespace lisfm
