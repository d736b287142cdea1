#include "mosaicloc/tracking/refine.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

#include <Eigen/LU>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "low_pass.hpp"
#include "mosaicloc/tracking/render_window.hpp"
#include "refine_kernels.hpp"
#include "render_window.hpp"
#include "visp_refine.hpp"

namespace mosaicloc::tracking {
namespace {

using Affine = Eigen::Matrix<double, 2, 3>;

// The low-passed reference around one template. Sample positions are raster coordinates
// relative to `origin` (the corner of the largest block the refinement may need); the block
// actually fetched may be smaller and starts `offset` px further in.
struct FilteredRaster {
  mosaic::RasterPatch region;
  cv::Mat raster;  // CV_32F, the size of region.image
  cv::Mat mask;    // region.mask eroded by the kernel radius (when not all mapped)
  int offset_x = 0, offset_y = 0;
  // Positions whose bilinear samples read only filtered pixels that do not depend on where
  // the block ends: lo <= x < hi.
  double lo_x = 0.0, lo_y = 0.0, hi_x = 0.0, hi_y = 0.0;
  bool whole = false;  // the largest block, filtered to its edges (every position may be tried)

  // The bilinear sample at raster position (x, y) into *value; false where the block does not
  // hold it or it touches unmapped floor.
  bool Sample(double x, double y, double* value) const {
    const int ix = static_cast<int>(x) - offset_x, iy = static_cast<int>(y) - offset_y;
    if (ix < 0 || iy < 0 || ix > raster.cols - 2 || iy > raster.rows - 2) return false;
    if (!region.all_mapped) {
      const std::uint8_t* m0 = mask.ptr<std::uint8_t>(iy) + ix;
      const std::uint8_t* m1 = mask.ptr<std::uint8_t>(iy + 1) + ix;
      if ((m0[0] & m0[1] & m1[0] & m1[1]) == 0) return false;
    }
    const float* p0 = raster.ptr<float>(iy) + ix;
    const float* p1 = raster.ptr<float>(iy + 1) + ix;
    const double fx = x - (ix + offset_x), fy = y - (iy + offset_y);
    const double top = p0[0] + fx * (p0[1] - p0[0]);
    const double bottom = p1[0] + fx * (p1[1] - p1[0]);
    *value = top + fy * (bottom - top);
    return true;
  }
};

// Fetches and filters the block `margin` px around `bounds`; the largest is `full_margin`.
// Filtered pixels at least the kernel radius R inside the block equal those of any larger
// block, so a smaller block gives the same samples wherever it is valid; only the largest is
// filtered to its edges (replicated), as every sample it may be asked for must be defined.
void LoadRaster(const ReferenceRaster& reference, const detail::RasterBounds& bounds, int margin, int full_margin,
                double sigma_px, FilteredRaster* out) {
  const int radius = detail::LowPassRadius(sigma_px);
  // Per-thread pixels: several templates are refined every frame.
  thread_local cv::Mat region_store;
  detail::FetchRegion(reference, bounds, margin, region_store, &out->region);
  out->offset_x = out->offset_y = full_margin - margin;
  out->whole = margin == full_margin;
  const cv::Mat& image = out->region.image;
  // Per-thread buffer: several templates are refined every frame.
  thread_local cv::Mat raster_store;
  out->raster = detail::ScratchImage(raster_store, image.size(), CV_32FC1);
  if (out->whole) {
    detail::GaussianLowPass(image, out->raster, sigma_px, CV_32F);
  } else {
    const cv::Rect interior(radius, radius, image.cols - 2 * radius, image.rows - 2 * radius);
    cv::Mat target = out->raster(interior);
    detail::GaussianLowPassRect(image, interior, target, sigma_px, CV_32F);
  }
  out->lo_x = out->offset_x + radius;
  out->lo_y = out->offset_y + radius;
  out->hi_x = out->offset_x + image.cols - 1 - radius;
  out->hi_y = out->offset_y + image.rows - 1 - radius;
  out->mask = out->region.mask;
  if (radius > 0 && !out->region.all_mapped) {
    const cv::Size k(2 * radius + 1, 2 * radius + 1);
    cv::erode(out->region.mask, out->mask, cv::getStructuringElement(cv::MORPH_RECT, k));
  }
}

// Tukey's biweight reweighting after the least-squares fit, from shift *t: the residuals of
// the normalised template against the raster, e_k = (M_k - mu) / sigma - T_k, get the weights
// (1 - (e_k / c)^2)^2 inside c = 4.685 x their robust standard deviation (1.4826 x the median
// |e_k|) and 0 outside, and Gauss-Newton steps of the weighted sum follow until the shift
// settles; the weights are those of the last residuals. Fills the covariance (the weighted
// residual variance times the inverse of the weighted normal matrix) and the unweighted ZNCC;
// false, with the failure set, when the weighted fit diverges, leaves the map or does not settle.
bool RobustPasses(const FilteredRaster& filtered, const std::vector<double>& base_x, const std::vector<double>& base_y,
                  const std::vector<double>& templ, const std::vector<double>& jac_x, const std::vector<double>& jac_y,
                  std::size_t n, const RefineOptions& options, Eigen::Vector2d* t, RefinedMatch* match) {
  thread_local std::vector<double> value, residual, magnitude;
  thread_local std::vector<unsigned char> known;
  value.resize(n);
  residual.resize(n);
  known.resize(n);
  Eigen::Matrix2d weighted_hessian = Eigen::Matrix2d::Identity();
  double weighted_e2 = 0.0, weight_sum = 0.0;
  double sum_e2 = 0.0;
  std::size_t used = 0;
  for (int iteration = 0; iteration < options.max_iterations; ++iteration) {
    // Samples at the current shift, and the raster's moments over the known ones.
    double sm = 0.0, smm = 0.0;
    used = 0;
    for (std::size_t k = 0; k < n; ++k) {
      known[k] = filtered.Sample(base_x[k] + t->x(), base_y[k] + t->y(), &value[k]) ? 1 : 0;
      if (!known[k]) continue;
      sm += value[k];
      smm += value[k] * value[k];
      ++used;
    }
    if (used < 8 || static_cast<double>(used) < options.min_mapped_fraction * static_cast<double>(n)) {
      match->failure = RefineFailure::kOffMap;
      return false;
    }
    const double count = static_cast<double>(used);
    const double mean_m = sm / count;
    const double std_m = std::sqrt(std::max(smm / count - mean_m * mean_m, 1e-12));
    magnitude.clear();
    sum_e2 = 0.0;
    for (std::size_t k = 0; k < n; ++k) {
      if (!known[k]) continue;
      residual[k] = (value[k] - mean_m) / std_m - templ[k];
      sum_e2 += residual[k] * residual[k];
      magnitude.push_back(std::abs(residual[k]));
    }
    const auto middle = magnitude.begin() + static_cast<std::ptrdiff_t>(magnitude.size() / 2);
    std::nth_element(magnitude.begin(), middle, magnitude.end());
    const double c = 4.685 * std::max(1.4826 * *middle, 1e-6);
    Eigen::Matrix2d h = Eigen::Matrix2d::Zero();
    Eigen::Vector2d gradient = Eigen::Vector2d::Zero();
    weighted_e2 = 0.0;
    weight_sum = 0.0;
    for (std::size_t k = 0; k < n; ++k) {
      if (!known[k]) continue;
      const double u = residual[k] / c;
      if (std::abs(u) >= 1.0) continue;
      const double w = (1.0 - u * u) * (1.0 - u * u);
      h(0, 0) += w * jac_x[k] * jac_x[k];
      h(0, 1) += w * jac_x[k] * jac_y[k];
      h(1, 1) += w * jac_y[k] * jac_y[k];
      gradient += w * residual[k] * Eigen::Vector2d(jac_x[k], jac_y[k]);
      weighted_e2 += w * residual[k] * residual[k];
      weight_sum += w;
    }
    h(1, 0) = h(0, 1);
    if (!(h.determinant() > 1e-12)) {
      match->failure = RefineFailure::kDiverged;
      match->detail = "no texture left after reweighting";
      return false;
    }
    weighted_hessian = h;
    const Eigen::Vector2d delta = -(h.inverse() * gradient);
    *t += delta;
    match->iterations += 1;
    if (!t->allFinite() || t->norm() > options.max_shift_px) {
      match->failure = RefineFailure::kDiverged;
      return false;
    }
    if (delta.norm() < options.tolerance_px) {
      const double dof = std::max(1.0, weight_sum - 2.0);
      match->covariance_px2 = (weighted_e2 / dof) * weighted_hessian.inverse();
      match->zncc = 1.0 - sum_e2 / (2.0 * static_cast<double>(used));
      return true;
    }
  }
  match->failure = RefineFailure::kNotConverged;
  return false;
}

// Inverse-compositional Gauss-Newton on the translation t of the template in the raster,
// with ZNCC normalisation of both sides:
//   min_t sum_k ( N[M](A x_k + b + t) - N[T](x_k) )^2,   N[f] = (f - mean f) / std f,
// where M is the raster, T the frame, x_k the template's pixels and [A | b] the current
// frame -> raster map. At the optimum M(A x + b + t) ~ T(x), so grad M ~ grad T A^-1:
// the Jacobian and the 2x2 Gauss-Newton matrix come from the template once (Baker and
// Matthews, "Lucas-Kanade 20 years on", 2004, section 3.2), and each iteration costs one
// bilinear sample per pixel. The normalisation makes the cost blind to gain and offset.
RefinedMatch RefineDirect(const cv::Mat& frame, const cv::Rect& rect, const ReferenceRaster& reference,
                          const Affine& frame_to_raster, const RefineOptions& options) {
  RefinedMatch match;
  const cv::Rect inner = rect & cv::Rect(1, 1, frame.cols - 2, frame.rows - 2);
  const int blur_radius = detail::LowPassRadius(options.prefilter_sigma_px);
  // The block every sample of a shift up to max_shift_px falls in; a refinement that stays
  // within a few pixels of its start (nearly all) needs only the smaller one.
  const int full_margin = static_cast<int>(std::ceil(options.max_shift_px)) + 2 + blur_radius;
  constexpr int kSlackPx = 2;
  const int margin = std::min(full_margin, blur_radius + 1 + kSlackPx);
  const detail::RasterBounds bounds = detail::BoundsOf(frame_to_raster, inner);

  // Both sides low-pass filtered alike: real floors carry detail up to the pixel scale, where
  // bilinear interpolation is a poor model of the image between samples and would bias the
  // sub-pixel estimate. The mask shrinks by the kernel radius so no unknown pixel leaks in.
  // The template's gradient needs the filtered frame on `inner` and one pixel around it.
  const cv::Rect gradient_rect(inner.x - 1, inner.y - 1, inner.width + 2, inner.height + 2);
  // Per-thread buffer: several templates are refined every frame.
  thread_local cv::Mat templ_store;
  cv::Mat templ_source = detail::ScratchImage(templ_store, gradient_rect.size(), CV_32FC1);
  detail::GaussianLowPassRect(frame, gradient_rect, templ_source, options.prefilter_sigma_px, CV_32F);
  FilteredRaster filtered;
  LoadRaster(reference, bounds, margin, full_margin, options.prefilter_sigma_px, &filtered);

  const Eigen::Matrix2d a = frame_to_raster.leftCols<2>();
  const Eigen::Matrix2d a_inv = a.inverse();
  const Eigen::Vector2d b = frame_to_raster.col(2) - Eigen::Vector2d(static_cast<double>(bounds.col0 - full_margin),
                                                                      static_cast<double>(bounds.row0 - full_margin));
  const int step = options.sampling;
  // Per-thread buffers, only ever grown.
  thread_local std::vector<double> base_x, base_y, templ, jac_x, jac_y;
  const std::size_t capacity = static_cast<std::size_t>((inner.width / step + 1) * (inner.height / step + 1));
  for (auto* v : {&base_x, &base_y, &templ, &jac_x, &jac_y}) {
    if (v->size() < capacity) v->resize(capacity);
  }
  // The template's sample grid: columns x0, x0 + step, ..., x1 and rows y0, ..., y1.
  const int x0 = inner.x, x1 = inner.x + (inner.width - 1) / step * step;
  const int y0 = inner.y, y1 = inner.y + (inner.height - 1) / step * step;
  // Raster position of grid point (x, y): a00 x + (a01 y + b0), a10 x + (a11 y + b1). Each is
  // monotonic in x and y in floating point too, so the grid's corners bound all of them.
  const auto raster_at = [&](int x, int y) {
    return Eigen::Vector2d(a(0, 0) * x + (a(0, 1) * y + b.x()), a(1, 0) * x + (a(1, 1) * y + b.y()));
  };
  double min_x = 1e300, min_y = 1e300, max_x = -1e300, max_y = -1e300;
  for (const int x : {x0, x1}) {
    for (const int y : {y0, y1}) {
      const Eigen::Vector2d r = raster_at(x, y);
      min_x = std::min(min_x, r.x());
      min_y = std::min(min_y, r.y());
      max_x = std::max(max_x, r.x());
      max_y = std::max(max_y, r.y());
    }
  }
  std::size_t n = 0;
  for (int y = y0; y <= y1; y += step) {
    const float* row = templ_source.ptr<float>(y - gradient_rect.y) - gradient_rect.x;
    const float* up = templ_source.ptr<float>(y - 1 - gradient_rect.y) - gradient_rect.x;
    const float* down = templ_source.ptr<float>(y + 1 - gradient_rect.y) - gradient_rect.x;
    const double row_x = a(0, 1) * y + b.x(), row_y = a(1, 1) * y + b.y();
    for (int x = x0; x <= x1; x += step, ++n) {
      const double gx = 0.5 * (row[x + 1] - row[x - 1]);
      const double gy = 0.5 * (down[x] - up[x]);
      base_x[n] = a(0, 0) * x + row_x;
      base_y[n] = a(1, 0) * x + row_y;
      templ[n] = row[x];
      jac_x[n] = gx * a_inv(0, 0) + gy * a_inv(1, 0);
      jac_y[n] = gx * a_inv(0, 1) + gy * a_inv(1, 1);
    }
  }
  const detail::RefineKernels kernels = detail::ChooseRefineKernels();
  double sum = 0.0, sum_sq = 0.0;
  kernels.moments(templ.data(), n, &sum, &sum_sq);
  const double mean_t = sum / static_cast<double>(n);
  const double std_t = std::sqrt(std::max(sum_sq / static_cast<double>(n) - mean_t * mean_t, 1e-12));
  // With the template normalised (sum T = 0, sum T^2 = n) and e_k = (M_k - mu) / sigma - T_k:
  //   sum_k J_k e_k = (sum_k J_k M_k - mu sum_k J_k) / sigma - sum_k J_k T_k,
  //   sum_k e_k^2  = 2 n - 2 sum_k M_k T_k / sigma,
  // so one pass of five running sums per iteration does it, with no per-pixel storage.
  // Off-map samples (only near the map's edge) take the general path with their own sums.
  detail::NormalisedSums normalised;
  kernels.normalise(templ.data(), jac_x.data(), jac_y.data(), n, mean_t, std_t, &normalised);
  Eigen::Matrix2d hessian;
  hessian(0, 0) = normalised.jxjx;
  hessian(0, 1) = normalised.jxjy;
  hessian(1, 1) = normalised.jyjy;
  const double sum_jx = normalised.jx, sum_jy = normalised.jy, sum_jxt = normalised.jxt, sum_jyt = normalised.jyt;
  hessian(1, 0) = hessian(0, 1);
  if (!(hessian.determinant() > 1e-12)) {
    match.failure = RefineFailure::kDiverged;
    match.detail = "no texture: the template has no gradient";
    return match;
  }
  Eigen::Vector2d t = Eigen::Vector2d::Zero();
  double sum_e2 = 0.0;
  std::size_t used = 0;
  bool converged = false;
  for (int iteration = 0; iteration < options.max_iterations; ++iteration) {
    match.iterations = iteration + 1;
    // All samples of this iteration within the filtered block, or the largest block.
    const bool within = min_x + t.x() >= filtered.lo_x && min_y + t.y() >= filtered.lo_y &&
                        max_x + t.x() < filtered.hi_x && max_y + t.y() < filtered.hi_y;
    if (!within && !filtered.whole) {
      LoadRaster(reference, bounds, full_margin, full_margin, options.prefilter_sigma_px, &filtered);
    }
    const float* pixels = filtered.raster.ptr<float>(0);
    const std::size_t stride = filtered.raster.step1();
    const int offset_x = filtered.offset_x, offset_y = filtered.offset_y;
    const bool all_known = filtered.region.all_mapped;
    double sm = 0.0, smm = 0.0, sjxm = 0.0, sjym = 0.0, smt = 0.0;
    double pjx = sum_jx, pjy = sum_jy, pjxt = sum_jxt, pjyt = sum_jyt, stt = static_cast<double>(n), st = 0.0;
    Eigen::Matrix2d h = hessian;
    used = 0;
    if (within && all_known) {
      // Every sample inside and known: no per-sample test.
      detail::SampleSums sums;
      kernels.sum_samples(base_x.data(), base_y.data(), jac_x.data(), jac_y.data(), templ.data(), n, t.x(), t.y(),
                          pixels, static_cast<std::ptrdiff_t>(stride), offset_x, offset_y, &sums);
      sm = sums.sm;
      smm = sums.smm;
      sjxm = sums.sjxm;
      sjym = sums.sjym;
      smt = sums.smt;
      used = n;
    } else {
      for (std::size_t k = 0; k < n; ++k) {
        double v = 0.0;
        if (!filtered.Sample(base_x[k] + t.x(), base_y[k] + t.y(), &v)) {
          // Take this sample out of the precomputed sums.
          pjx -= jac_x[k];
          pjy -= jac_y[k];
          pjxt -= jac_x[k] * templ[k];
          pjyt -= jac_y[k] * templ[k];
          stt -= templ[k] * templ[k];
          st -= templ[k];
          h(0, 0) -= jac_x[k] * jac_x[k];
          h(0, 1) -= jac_x[k] * jac_y[k];
          h(1, 1) -= jac_y[k] * jac_y[k];
          continue;
        }
        sm += v;
        smm += v * v;
        sjxm += jac_x[k] * v;
        sjym += jac_y[k] * v;
        smt += v * templ[k];
        ++used;
      }
    }
    if (static_cast<double>(used) < options.min_mapped_fraction * static_cast<double>(n)) {
      match.failure = RefineFailure::kOffMap;
      return match;
    }
    h(1, 0) = h(0, 1);
    const double count = static_cast<double>(used);
    const double mean_m = sm / count;
    const double std_m = std::sqrt(std::max(smm / count - mean_m * mean_m, 1e-12));
    const Eigen::Vector2d gradient((sjxm - mean_m * pjx) / std_m - pjxt, (sjym - mean_m * pjy) / std_m - pjyt);
    // sum e^2 over the used samples; st, stt correct for samples left out (their T is not
    // re-normalised: near the edge the score is slightly pessimistic, never the position).
    sum_e2 = std::max(0.0, count + stt - 2.0 * (smt - mean_m * st) / std_m);
    const Eigen::Vector2d delta = -(h.inverse() * gradient);
    t += delta;
    if (!t.allFinite() || t.norm() > options.max_shift_px) {
      match.failure = RefineFailure::kDiverged;
      return match;
    }
    if (delta.norm() < options.tolerance_px) {
      converged = true;
      break;
    }
  }
  if (!converged) {
    match.failure = RefineFailure::kNotConverged;
    return match;
  }
  if (options.robust) {
    // The reweighted fit may move further: every sample it may ask for.
    if (!filtered.whole) LoadRaster(reference, bounds, full_margin, full_margin, options.prefilter_sigma_px, &filtered);
    if (!RobustPasses(filtered, base_x, base_y, templ, jac_x, jac_y, n, options, &t, &match)) return match;
  } else {
    const double dof = std::max(1.0, static_cast<double>(used) - 2.0);
    match.covariance_px2 = (sum_e2 / dof) * hessian.inverse();
    match.zncc = 1.0 - sum_e2 / (2.0 * static_cast<double>(used));
  }
  const Eigen::Vector2d centre(rect.x + 0.5 * (rect.width - 1), rect.y + 0.5 * (rect.height - 1));
  match.centre_raster = ApplyAffine(frame_to_raster, centre) + t;
  return match;
}

// ZNCC between the template `rect` of the frame and the window sampled bilinearly at the
// template's pixels + shift (window pixel = frame pixel - origin + shift), both low-passed by
// `sigma` like the direct method's images, so the scores of all methods compare.
double SubPixelZncc(const cv::Mat& frame, const cv::Rect& rect, const cv::Mat& window, const cv::Point& origin,
                    const Eigen::Vector2d& shift, double sigma) {
  cv::Mat templ, win;
  detail::GaussianLowPass(frame(rect), templ, sigma, CV_32F);
  detail::GaussianLowPass(window, win, sigma, CV_32F);
  double st = 0.0, sm = 0.0, stt = 0.0, smm = 0.0, stm = 0.0;
  int n = 0;
  const cv::Mat no_mask;
  for (int y = 0; y < rect.height; ++y) {
    for (int x = 0; x < rect.width; ++x) {
      double m = 0.0;
      if (!detail::Sample<float>(win, no_mask, true, rect.x - origin.x + x + shift.x(),
                                 rect.y - origin.y + y + shift.y(), &m)) {
        continue;
      }
      const double t = templ.at<float>(y, x);
      st += t;
      sm += m;
      stt += t * t;
      smm += m * m;
      stm += t * m;
      ++n;
    }
  }
  if (n < 2) return 0.0;
  const double var_t = stt / n - (st / n) * (st / n), var_m = smm / n - (sm / n) * (sm / n);
  if (var_t <= 0.0 || var_m <= 0.0) return 0.0;
  return (stm / n - (st / n) * (sm / n)) / std::sqrt(var_t * var_m);
}

// ViSP's headers do not compile as C++20; the part that uses them is a C++17 island
// (visp_refine.cpp) behind a plain interface.
RefinedMatch RefineVisp(const cv::Mat& frame, const cv::Rect& rect, const ReferenceRaster& reference,
                        const Affine& frame_to_raster, const RefineOptions& options) {
  RefinedMatch match;
  constexpr int kBorder = 2;
  const cv::Rect crop_rect = cv::Rect(rect.x - kBorder, rect.y - kBorder, rect.width + 2 * kBorder,
                                      rect.height + 2 * kBorder) &
                             cv::Rect(0, 0, frame.cols, frame.rows);
  const int pad = static_cast<int>(std::ceil(options.max_shift_px)) + kBorder + 2;
  const cv::Point origin(rect.x - pad, rect.y - pad);
  cv::Mat mask;
  const cv::Mat window =
      RenderWindow(reference, frame_to_raster, origin, cv::Size(rect.width + 2 * pad, rect.height + 2 * pad), &mask);
  const double mapped = static_cast<double>(cv::countNonZero(mask)) / static_cast<double>(mask.total());
  if (mapped < options.min_mapped_fraction) {
    match.failure = RefineFailure::kOffMap;
    return match;
  }
  detail::VispRequest request;
  request.ssd = options.method == RefineMethod::kVispSsd;
  request.warp = options.warp == RefineWarp::kTranslation ? detail::VispWarp::kTranslation
                 : options.warp == RefineWarp::kSrt       ? detail::VispWarp::kSrt
                                                          : detail::VispWarp::kHomography;
  request.sampling = options.sampling;
  request.max_iterations = options.max_iterations;
  request.pyramid_levels = options.visp_pyramid_levels;
  request.zone = cv::Rect(rect.x - crop_rect.x, rect.y - crop_rect.y, rect.width, rect.height);
  request.start_u = crop_rect.x - origin.x;
  request.start_v = crop_rect.y - origin.y;
  const detail::VispAnswer answer = detail::TrackWithVisp(frame(crop_rect), window, request);
  match.iterations = answer.iterations;
  if (!answer.ok) {
    match.failure = answer.diverged ? RefineFailure::kDiverged : RefineFailure::kVispError;
    match.detail = answer.message;
    return match;
  }
  // Where the template's centre went, relative to where it was predicted.
  const Eigen::Vector2d moved(answer.centre_u - (request.zone.x + 0.5 * (rect.width - 1) + request.start_u),
                              answer.centre_v - (request.zone.y + 0.5 * (rect.height - 1) + request.start_v));
  if (!moved.allFinite() || moved.norm() > options.max_shift_px) {
    match.failure = RefineFailure::kDiverged;
    return match;
  }
  const Eigen::Vector2d centre(rect.x + 0.5 * (rect.width - 1), rect.y + 0.5 * (rect.height - 1));
  match.centre_raster = ApplyAffine(frame_to_raster, centre + moved);
  match.rotation_rad = answer.rotation_rad;
  // Score: our own ZNCC at the solution (ViSP has no public cost getter for its ZNCC trackers).
  match.zncc = SubPixelZncc(frame, rect, window, origin, moved, options.prefilter_sigma_px);
  // ViSP exposes no information matrix: take an isotropic 0.02 px floor grown by the
  // residual (1 - ZNCC), so weaker matches weigh less, and express it in raster px.
  const double sigma_frame_px = 0.02 + 0.5 * std::max(0.0, 1.0 - match.zncc);
  const double raster_px2_per_frame_px2 = std::abs(frame_to_raster.leftCols<2>().determinant());
  match.covariance_px2 = Eigen::Matrix2d::Identity() * (sigma_frame_px * sigma_frame_px * raster_px2_per_frame_px2);
  return match;
}

}  // namespace

bool RefineOptions::Check(std::string* why) const {
  auto fail = [why](const char* message) {
    if (why != nullptr) *why = message;
    return false;
  };
  if (max_iterations < 1 || max_iterations > 1000) return fail("max_iterations must be in [1, 1000]");
  if (!(tolerance_px > 0.0)) return fail("tolerance_px must be > 0");
  if (!(max_shift_px > 0.0 && max_shift_px <= 64.0)) return fail("max_shift_px must be in (0, 64]");
  if (sampling < 1 || sampling > 8) return fail("sampling must be in [1, 8]");
  if (visp_pyramid_levels < 1 || visp_pyramid_levels > 4) return fail("visp_pyramid_levels must be in [1, 4]");
  if (!(prefilter_sigma_px >= 0.0 && prefilter_sigma_px <= 5.0)) return fail("prefilter_sigma_px must be in [0, 5]");
  if (!(min_mapped_fraction > 0.0 && min_mapped_fraction <= 1.0)) return fail("min_mapped_fraction must be in (0, 1]");
  if (method == RefineMethod::kDirect && warp != RefineWarp::kTranslation) {
    return fail("warp must be translation for the direct method, which estimates a translation only");
  }
  return true;
}

const char* ToString(RefineMethod method) {
  switch (method) {
    case RefineMethod::kDirect: return "direct";
    case RefineMethod::kVispSsd: return "visp-ssd";
    case RefineMethod::kVispZncc: return "visp-zncc";
  }
  return "unknown";
}

const char* ToString(RefineWarp warp) {
  switch (warp) {
    case RefineWarp::kTranslation: return "translation";
    case RefineWarp::kSrt: return "srt";
    case RefineWarp::kHomography: return "homography";
  }
  return "unknown";
}

const char* ToString(RefineFailure failure) {
  switch (failure) {
    case RefineFailure::kNone: return "ok";
    case RefineFailure::kOffMap: return "off map";
    case RefineFailure::kDiverged: return "diverged";
    case RefineFailure::kNotConverged: return "not converged";
    case RefineFailure::kVispError: return "ViSP error";
  }
  return "unknown";
}

RefinedMatch RefineTemplate(const cv::Mat& frame, const cv::Rect& rect, const ReferenceRaster& reference,
                            const Affine& frame_to_raster, const RefineOptions& options) {
  if (options.method == RefineMethod::kDirect) return RefineDirect(frame, rect, reference, frame_to_raster, options);
  return RefineVisp(frame, rect, reference, frame_to_raster, options);
}

}  // namespace mosaicloc::tracking
