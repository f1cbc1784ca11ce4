#include "core/errors.h"

namespace lisfm {

InputError::InputError(const std::string& message) : std::runtime_error(message) {}

InputError::InputError(const std::string& path,
                       const std::string& location,
                       const std::string& message)
    : std::runtime_error(path + (location.empty() ? "" : ":" + location) + ": " +
                         message) {}

namespace internal {
void ThrowCheckFailure(const char* file,
                       int line,
                       const std::string& condition,
                       const std::string& detail) {
  std::ostringstream s;
  s << "internal check failed at " << file << ":" << line << ": " << condition
    << detail;
  throw InternalError(s.str());
}
}  // namespace internal

}  // namespace lisfm
