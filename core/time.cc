#include "core/time.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <cinttypes>
#include <cstdio>

namespace lisfm {

bool ParseSecondsToNs(const std::string& text, TimestampNs* t_ns) {
  size_t i = 0;
  while (i < text.size() && std::isspace(static_cast<unsigned char>(text[i]))) ++i;
  bool negative = false;
  if (i < text.size() && (text[i] == '-' || text[i] == '+')) {
    negative = text[i] == '-';
    ++i;
  }
  int64_t whole = 0;
  int whole_digits = 0;
  while (i < text.size() && std::isdigit(static_cast<unsigned char>(text[i]))) {
    if (whole > (INT64_MAX / kNsPerSecond) / 10) return false;
    whole = whole * 10 + (text[i] - '0');
    ++i;
    ++whole_digits;
  }
  int64_t frac = 0;
  int frac_digits = 0;
  if (i < text.size() && text[i] == '.') {
    ++i;
    while (i < text.size() && std::isdigit(static_cast<unsigned char>(text[i]))) {
      if (frac_digits < 9) {
        frac = frac * 10 + (text[i] - '0');
        ++frac_digits;
      } else if (frac_digits == 9) {
        if (text[i] >= '5') ++frac;  // round half up at the 10th digit
        ++frac_digits;
      }
      ++i;
    }
  }
  if (whole_digits == 0 && frac_digits == 0) return false;
  // Scientific notation or trailing garbage is not a plain decimal: fall back.
  if (i < text.size() && !std::isspace(static_cast<unsigned char>(text[i]))) {
    char* end = nullptr;
    const double v = std::strtod(text.c_str(), &end);
    if (end == text.c_str()) return false;
    while (*end != '\0' && std::isspace(static_cast<unsigned char>(*end))) ++end;
    if (*end != '\0' || !IsRepresentableAsNs(v)) return false;
    *t_ns = SecondsToNs(v);
    return true;
  }
  for (int k = std::min(frac_digits, 9); k < 9; ++k) frac *= 10;
  // whole <= 9223372039 here (the digit loop's guard); the sum must fit in int64.
  if (whole > INT64_MAX / kNsPerSecond || frac > INT64_MAX - whole * kNsPerSecond) return false;
  const int64_t value = whole * kNsPerSecond + frac;
  *t_ns = negative ? -value : value;
  return true;
}

std::string FormatNsAsSeconds(TimestampNs t_ns) {
  const bool negative = t_ns < 0;
  const uint64_t a = negative ? static_cast<uint64_t>(-(t_ns + 1)) + 1 : t_ns;
  char buf[48];
  std::snprintf(buf, sizeof(buf), "%s%" PRIu64 ".%09" PRIu64, negative ? "-" : "",
                a / kNsPerSecond, a % kNsPerSecond);
  return buf;
}

}  // namespace lisfm
