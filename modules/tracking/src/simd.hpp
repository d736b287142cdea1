#pragma once

// Run-time choice of the instruction set for the tracker's hot loops. The AVX2 builds of a
// loop do the same IEEE operations in the same order as the baseline build (no FMA, no
// re-association), only more lanes at a time, so both give bit-identical results.

#if defined(__x86_64__) && defined(__GNUC__)
#define MOSAICLOC_TRACKING_AVX2 1
#define MOSAICLOC_TARGET_AVX2 __attribute__((target("avx2")))
#else
#define MOSAICLOC_TARGET_AVX2
#endif

#define MOSAICLOC_ALWAYS_INLINE __attribute__((always_inline)) inline

namespace mosaicloc::tracking::detail {

/// True when the processor has AVX2 and it has not been turned off with SetAvx2Allowed.
bool UseAvx2();

/// Tests compare the two builds of each loop: false makes UseAvx2() false until set back.
void SetAvx2Allowed(bool allowed);

}  // namespace mosaicloc::tracking::detail
