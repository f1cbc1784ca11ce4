// Time stamps: int64 nanoseconds everywhere in memory, CSV files and file names
// (DESIGN.md "Time"). Seconds (double) only at the TUM boundary.
#pragma once

#include <cmath>
#include <cstdint>
#include <string>

namespace lisfm {

using TimestampNs = int64_t;  // nanoseconds since an arbitrary epoch (sensor clock)

constexpr int64_t kNsPerSecond = 1000000000LL;

inline double NsToSeconds(TimestampNs t_ns) { return static_cast<double>(t_ns) * 1e-9; }

// Rounds to the nearest nanosecond. Exact for the 9 decimals TUM files carry
// up to ~1e7 s of magnitude, because the integer and fractional parts are
// split before scaling.
inline TimestampNs SecondsToNs(double t_s) {
  const double whole = std::floor(t_s);
  return static_cast<TimestampNs>(whole) * kNsPerSecond +
         static_cast<TimestampNs>(std::llround((t_s - whole) * 1e9));
}

// Parses a decimal seconds string ("1646307131.123456789") to ns without going
// through double, so 19-digit stamps keep every digit. Returns false on bad syntax.
bool ParseSecondsToNs(const std::string& text, TimestampNs* t_ns);

// Formats ns as seconds with 9 decimals ("1646307131.123456789").
std::string FormatNsAsSeconds(TimestampNs t_ns);

}  // namespace lisfm
