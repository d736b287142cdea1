#include "simd.hpp"

#include <atomic>

namespace mosaicloc::tracking::detail {
namespace {

std::atomic<bool> avx2_allowed{true};

}  // namespace

bool UseAvx2() {
#ifdef MOSAICLOC_TRACKING_AVX2
  static const bool have = __builtin_cpu_supports("avx2");
  return have && avx2_allowed.load(std::memory_order_relaxed);
#else
  return false;
#endif
}

void SetAvx2Allowed(bool allowed) { avx2_allowed.store(allowed, std::memory_order_relaxed); }

}  // namespace mosaicloc::tracking::detail
