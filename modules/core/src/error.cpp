#include "mosaicloc/core/error.hpp"

namespace mosaicloc::core {

void ThrowInvalidInput(const std::string& message) { throw Error(ErrorKind::kInvalidInput, message); }

void ThrowRuntime(const std::string& message) { throw Error(ErrorKind::kRuntime, message); }

}  // namespace mosaicloc::core
