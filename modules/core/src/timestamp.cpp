#include "mosaicloc/core/timestamp.hpp"

#include <cmath>

namespace mosaicloc::core {

Timestamp Timestamp::FromSeconds(double seconds) {
  return Timestamp(std::llround(seconds * 1e9));
}

Duration FromSeconds(double seconds) { return Duration(std::llround(seconds * 1e9)); }

}  // namespace mosaicloc::core
