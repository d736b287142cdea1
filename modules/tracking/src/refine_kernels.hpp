#pragma once

#include <cstddef>

// The direct refinement's loops over a template's samples (RefineTemplate, kDirect), in a
// plain and an AVX2 build each; see refine.cpp for the Gauss-Newton they serve.

namespace mosaicloc::tracking::detail {

// Running sums of one Gauss-Newton iteration over the samples v_k = M(x_k + t):
// sum v, sum v^2, sum Jx v, sum Jy v, sum v T.
struct SampleSums {
  double sm = 0.0, smm = 0.0, sjxm = 0.0, sjym = 0.0, smt = 0.0;
};

// Sums over the normalised template T and Jacobian J: J J^T (three entries), J and J T.
struct NormalisedSums {
  double jxjx = 0.0, jxjy = 0.0, jyjy = 0.0, jx = 0.0, jy = 0.0, jxt = 0.0, jyt = 0.0;
};

// The builds of the loops this processor runs (AVX2 when UseAvx2()). Both builds of each loop
// sum in the same order, so they agree bit for bit.
struct RefineKernels {
  // The sum and the sum of squares of t[0, n): the template's set-up sums.
  void (*moments)(const double* t, std::size_t n, double* sum, double* sum_sq);
  // T <- (T - mean) / sd, J <- J / sd (as products with 1 / sd), and the sums over them.
  void (*normalise)(double* templ, double* jac_x, double* jac_y, std::size_t n, double mean, double sd,
                    NormalisedSums* out);
  // The samples v_k of the template's points (base_x[k], base_y[k]) + (tx, ty) in the float
  // raster `pixels` (row stride `stride`, point (x, y) at pixel (x - offset_x, y - offset_y)),
  // every one of them inside, and the five SampleSums over them.
  void (*sum_samples)(const double* base_x, const double* base_y, const double* jac_x, const double* jac_y,
                      const double* templ, std::size_t n, double tx, double ty, const float* pixels,
                      std::ptrdiff_t stride, int offset_x, int offset_y, SampleSums* sums);
};
RefineKernels ChooseRefineKernels();

}  // namespace mosaicloc::tracking::detail
