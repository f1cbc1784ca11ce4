#include "core/option_check.h"

#include <cstdio>

#include "core/logging.h"

namespace lisfm {
namespace {

OptionCheckFailure& ThreadFailure() {
  thread_local OptionCheckFailure failure;
  return failure;
}

}  // namespace

std::string OptionCheckFailure::ToString() const {
  return name + " = " + value + " (must be " + requirement + ")";
}

const OptionCheckFailure& LastOptionCheckFailure() { return ThreadFailure(); }

namespace internal {

void RecordOptionCheckFailure(const void* field,
                              const std::string& name,
                              const std::string& value,
                              const std::string& requirement) {
  OptionCheckFailure& f = ThreadFailure();
  f.field = field;
  f.name = name;
  f.value = value;
  f.requirement = requirement;
  LogDebug("option check failed: {}", f.ToString());
}

void PrefixOptionCheckFailure(const std::string& prefix) {
  OptionCheckFailure& f = ThreadFailure();
  f.name = prefix + "." + f.name;
}

std::string FormatOptionNumber(double value) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.15g", value);
  return buf;
}

}  // namespace internal
}  // namespace lisfm
