#include "mosaicloc/tracking/refine.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

#include <Eigen/LU>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "low_pass.hpp"
#include "mosaicloc/mosaic/tile_store.hpp"
#include "visp_refine.hpp"

namespace mosaicloc::tracking {
namespace {

using Affine = Eigen::Matrix<double, 2, 3>;

// The raster block that holds every point frame_to_raster maps `rect` to, plus `margin` px.
mosaic::RasterPatch FetchRegion(const ReferenceRaster& reference, const Affine& frame_to_raster, const cv::Rect& rect,
                                int margin) {
  double min_x = 1e300, min_y = 1e300, max_x = -1e300, max_y = -1e300;
  for (const int x : {rect.x, rect.x + rect.width - 1}) {
    for (const int y : {rect.y, rect.y + rect.height - 1}) {
      const Eigen::Vector2d r = ApplyAffine(frame_to_raster, Eigen::Vector2d(x, y));
      min_x = std::min(min_x, r.x());
      min_y = std::min(min_y, r.y());
      max_x = std::max(max_x, r.x());
      max_y = std::max(max_y, r.y());
    }
  }
  const auto col0 = static_cast<std::int64_t>(std::floor(min_x)) - margin;
  const auto row0 = static_cast<std::int64_t>(std::floor(min_y)) - margin;
  const auto col1 = static_cast<std::int64_t>(std::ceil(max_x)) + margin;
  const auto row1 = static_cast<std::int64_t>(std::ceil(max_y)) + margin;
  return reference.Region(col0, row0, static_cast<int>(col1 - col0 + 1), static_cast<int>(row1 - row0 + 1));
}

// Bilinear sample of an image of T at (x, y); false when a source pixel is outside or unknown.
template <typename T>
inline bool Sample(const cv::Mat& image, const cv::Mat& mask, bool all_known, double x, double y, double* value) {
  const double fx0 = std::floor(x), fy0 = std::floor(y);
  const int ix = static_cast<int>(fx0), iy = static_cast<int>(fy0);
  if (ix < 0 || iy < 0 || ix + 1 >= image.cols || iy + 1 >= image.rows) return false;
  const T* p = image.ptr<T>(iy) + ix;
  const T* q = image.ptr<T>(iy + 1) + ix;
  if (!all_known) {
    const std::uint8_t* m = mask.ptr<std::uint8_t>(iy) + ix;
    const std::uint8_t* n = m + mask.step[0];
    if ((m[0] & m[1] & n[0] & n[1]) == 0) return false;
  }
  const double fx = x - fx0, fy = y - fy0;
  *value = (1.0 - fy) * ((1.0 - fx) * p[0] + fx * p[1]) + fy * ((1.0 - fx) * q[0] + fx * q[1]);
  return true;
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
  const int margin = static_cast<int>(std::ceil(options.max_shift_px)) + 2 + blur_radius;
  const mosaic::RasterPatch region = FetchRegion(reference, frame_to_raster, inner, margin);

  // Both sides low-pass filtered alike: real floors carry detail up to the pixel scale, where
  // bilinear interpolation is a poor model of the image between samples and would bias the
  // sub-pixel estimate. The mask shrinks by the kernel radius so no unknown pixel leaks in.
  cv::Mat raster_mask = region.mask;
  const bool all_known = region.all_mapped;
  const cv::Rect around = cv::Rect(inner.x - 1 - blur_radius, inner.y - 1 - blur_radius,
                                   inner.width + 2 + 2 * blur_radius, inner.height + 2 + 2 * blur_radius) &
                          cv::Rect(0, 0, frame.cols, frame.rows);
  // Per-thread buffers: several templates are refined every frame.
  thread_local cv::Mat templ_store, raster_store;
  cv::Mat templ_source = detail::ScratchImage(templ_store, around.size(), CV_32FC1);
  cv::Mat raster = detail::ScratchImage(raster_store, region.image.size(), CV_32FC1);
  detail::GaussianLowPass(frame(around), templ_source, options.prefilter_sigma_px, CV_32F);
  detail::GaussianLowPass(region.image, raster, options.prefilter_sigma_px, CV_32F);
  if (blur_radius > 0 && !all_known) {
    const cv::Size k(2 * blur_radius + 1, 2 * blur_radius + 1);
    cv::erode(region.mask, raster_mask, cv::getStructuringElement(cv::MORPH_RECT, k));
  }

  const Eigen::Matrix2d a = frame_to_raster.leftCols<2>();
  const Eigen::Matrix2d a_inv = a.inverse();
  const Eigen::Vector2d b = frame_to_raster.col(2) - Eigen::Vector2d(static_cast<double>(region.col0),
                                                                      static_cast<double>(region.row0));
  const int step = options.sampling;
  std::vector<double> base_x, base_y, templ, jac_x, jac_y;
  const std::size_t capacity = static_cast<std::size_t>((inner.width / step + 1) * (inner.height / step + 1));
  for (auto* v : {&base_x, &base_y, &templ, &jac_x, &jac_y}) v->reserve(capacity);
  double sum = 0.0, sum_sq = 0.0;
  for (int y = inner.y; y < inner.y + inner.height; y += step) {
    const float* row = templ_source.ptr<float>(y - around.y) - around.x;
    const float* up = templ_source.ptr<float>(y - 1 - around.y) - around.x;
    const float* down = templ_source.ptr<float>(y + 1 - around.y) - around.x;
    for (int x = inner.x; x < inner.x + inner.width; x += step) {
      const double gx = 0.5 * (row[x + 1] - row[x - 1]);
      const double gy = 0.5 * (down[x] - up[x]);
      const Eigen::Vector2d r = a * Eigen::Vector2d(x, y) + b;
      base_x.push_back(r.x());
      base_y.push_back(r.y());
      templ.push_back(row[x]);
      jac_x.push_back(gx * a_inv(0, 0) + gy * a_inv(1, 0));
      jac_y.push_back(gx * a_inv(0, 1) + gy * a_inv(1, 1));
      sum += row[x];
      sum_sq += static_cast<double>(row[x]) * row[x];
    }
  }
  const std::size_t n = templ.size();
  const double mean_t = sum / static_cast<double>(n);
  const double std_t = std::sqrt(std::max(sum_sq / static_cast<double>(n) - mean_t * mean_t, 1e-12));
  Eigen::Matrix2d hessian = Eigen::Matrix2d::Zero();
  for (std::size_t k = 0; k < n; ++k) {
    templ[k] = (templ[k] - mean_t) / std_t;
    jac_x[k] /= std_t;
    jac_y[k] /= std_t;
    hessian(0, 0) += jac_x[k] * jac_x[k];
    hessian(0, 1) += jac_x[k] * jac_y[k];
    hessian(1, 1) += jac_y[k] * jac_y[k];
  }
  hessian(1, 0) = hessian(0, 1);
  if (!(hessian.determinant() > 1e-12)) {
    match.failure = RefineFailure::kDiverged;
    match.detail = "no texture: the template has no gradient";
    return match;
  }

  // With the template normalised (sum T = 0, sum T^2 = n) and e_k = (M_k - mu) / sigma - T_k:
  //   sum_k J_k e_k = (sum_k J_k M_k - mu sum_k J_k) / sigma - sum_k J_k T_k,
  //   sum_k e_k^2  = 2 n - 2 sum_k M_k T_k / sigma,
  // so one pass of five running sums per iteration does it, with no per-pixel storage.
  // Off-map samples (only near the map's edge) take the general path with their own sums.
  double sum_jx = 0.0, sum_jy = 0.0, sum_jxt = 0.0, sum_jyt = 0.0;
  for (std::size_t k = 0; k < n; ++k) {
    sum_jx += jac_x[k];
    sum_jy += jac_y[k];
    sum_jxt += jac_x[k] * templ[k];
    sum_jyt += jac_y[k] * templ[k];
  }
  const float* pixels = raster.ptr<float>(0);
  const std::size_t stride = raster.step1();
  const int max_col = raster.cols - 2, max_row = raster.rows - 2;
  Eigen::Vector2d t = Eigen::Vector2d::Zero();
  double sum_e2 = 0.0;
  std::size_t used = 0;
  bool converged = false;
  for (int iteration = 0; iteration < options.max_iterations; ++iteration) {
    match.iterations = iteration + 1;
    double sm = 0.0, smm = 0.0, sjxm = 0.0, sjym = 0.0, smt = 0.0;
    double pjx = sum_jx, pjy = sum_jy, pjxt = sum_jxt, pjyt = sum_jyt, stt = static_cast<double>(n), st = 0.0;
    Eigen::Matrix2d h = hessian;
    used = 0;
    for (std::size_t k = 0; k < n; ++k) {
      const double x = base_x[k] + t.x(), y = base_y[k] + t.y();
      const int ix = static_cast<int>(x), iy = static_cast<int>(y);  // x, y > 0 by the margin
      bool ok = ix >= 0 && iy >= 0 && ix <= max_col && iy <= max_row;
      if (ok && !all_known) {
        const std::uint8_t* m0 = raster_mask.ptr<std::uint8_t>(iy) + ix;
        const std::uint8_t* m1 = raster_mask.ptr<std::uint8_t>(iy + 1) + ix;
        ok = (m0[0] & m0[1] & m1[0] & m1[1]) != 0;
      }
      if (!ok) {
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
      const float* p0 = pixels + static_cast<std::size_t>(iy) * stride + ix;
      const float* p1 = p0 + stride;
      const double fx = x - ix, fy = y - iy;
      const double top = p0[0] + fx * (p0[1] - p0[0]);
      const double bottom = p1[0] + fx * (p1[1] - p1[0]);
      const double v = top + fy * (bottom - top);
      sm += v;
      smm += v * v;
      sjxm += jac_x[k] * v;
      sjym += jac_y[k] * v;
      smt += v * templ[k];
      ++used;
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
  const double dof = std::max(1.0, static_cast<double>(used) - 2.0);
  match.covariance_px2 = (sum_e2 / dof) * hessian.inverse();
  match.zncc = 1.0 - sum_e2 / (2.0 * static_cast<double>(used));
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
      if (!Sample<float>(win, no_mask, true, rect.x - origin.x + x + shift.x(), rect.y - origin.y + y + shift.y(),
                         &m)) {
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
  if (max_iterations < 1) return fail("max_iterations must be >= 1");
  if (!(tolerance_px > 0.0)) return fail("tolerance_px must be > 0");
  if (!(max_shift_px > 0.0 && max_shift_px <= 64.0)) return fail("max_shift_px must be in (0, 64]");
  if (sampling < 1 || sampling > 8) return fail("sampling must be in [1, 8]");
  if (visp_pyramid_levels < 1 || visp_pyramid_levels > 4) return fail("visp_pyramid_levels must be in [1, 4]");
  if (!(prefilter_sigma_px >= 0.0 && prefilter_sigma_px <= 5.0)) return fail("prefilter_sigma_px must be in [0, 5]");
  if (!(min_mapped_fraction > 0.0 && min_mapped_fraction <= 1.0)) return fail("min_mapped_fraction must be in (0, 1]");
  if (method == RefineMethod::kDirect && warp != RefineWarp::kTranslation) {
    return fail("the direct method estimates a translation only (warp: translation)");
  }
  return true;
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

cv::Mat RenderWindow(const ReferenceRaster& reference, const Affine& frame_to_raster, const cv::Point& origin,
                     const cv::Size& size, cv::Mat* mask) {
  const cv::Rect rect(origin, size);
  const mosaic::RasterPatch region = FetchRegion(reference, frame_to_raster, rect, 2);
  const Eigen::Matrix2d a = frame_to_raster.leftCols<2>();
  const Eigen::Vector2d b = frame_to_raster.col(2) - Eigen::Vector2d(static_cast<double>(region.col0),
                                                                      static_cast<double>(region.row0));
  cv::Mat out(size, CV_8UC1);
  if (mask != nullptr) mask->create(size, CV_8UC1);
  // Every sample inside the block and every block pixel known (the usual case, away from the
  // map's edge): the same arithmetic as Sample without its per-pixel checks. The sample
  // positions are an affine image of the window, so they lie within the hull of its corners.
  bool inside = region.all_mapped;
  for (const int x : {0, size.width - 1}) {
    for (const int y : {0, size.height - 1}) {
      const Eigen::Vector2d r = a * Eigen::Vector2d(origin.x + x, origin.y + y) + b;
      inside = inside && r.x() >= 0.0 && r.y() >= 0.0 && r.x() < region.image.cols - 1.0 &&
               r.y() < region.image.rows - 1.0;
    }
  }
  if (inside) {
    const std::uint8_t* pixels = region.image.ptr<std::uint8_t>(0);
    const std::size_t stride = region.image.step[0];
    for (int y = 0; y < size.height; ++y) {
      auto* o = out.ptr<std::uint8_t>(y);
      const Eigen::Vector2d row_start = a * Eigen::Vector2d(origin.x, origin.y + y) + b;
      for (int x = 0; x < size.width; ++x) {
        const double rx = row_start.x() + a(0, 0) * x, ry = row_start.y() + a(1, 0) * x;
        // rx, ry >= 0: truncation is the floor (std::floor is a library call without SSE4.1).
        const auto ix = static_cast<std::size_t>(rx), iy = static_cast<std::size_t>(ry);
        const std::uint8_t* p = pixels + iy * stride + ix;
        const std::uint8_t* q = p + stride;
        const double fx = rx - static_cast<double>(ix), fy = ry - static_cast<double>(iy);
        const double v = (1.0 - fy) * ((1.0 - fx) * p[0] + fx * p[1]) + fy * ((1.0 - fx) * q[0] + fx * q[1]);
        o[x] = static_cast<std::uint8_t>(v + 0.5);
      }
    }
    if (mask != nullptr) mask->setTo(cv::Scalar(255));
    return out;
  }
  for (int y = 0; y < size.height; ++y) {
    auto* o = out.ptr<std::uint8_t>(y);
    std::uint8_t* m = mask != nullptr ? mask->ptr<std::uint8_t>(y) : nullptr;
    const Eigen::Vector2d row_start = a * Eigen::Vector2d(origin.x, origin.y + y) + b;
    for (int x = 0; x < size.width; ++x) {
      const double rx = row_start.x() + a(0, 0) * x, ry = row_start.y() + a(1, 0) * x;
      double v = 0.0;
      const bool known = Sample<std::uint8_t>(region.image, region.mask, region.all_mapped, rx, ry, &v);
      o[x] = known ? static_cast<std::uint8_t>(v + 0.5) : mosaic::kUnmapped;  // v in [0, 255]
      if (m != nullptr) m[x] = known ? 255 : 0;
    }
  }
  return out;
}

RefinedMatch RefineTemplate(const cv::Mat& frame, const cv::Rect& rect, const ReferenceRaster& reference,
                            const Affine& frame_to_raster, const RefineOptions& options) {
  if (options.method == RefineMethod::kDirect) return RefineDirect(frame, rect, reference, frame_to_raster, options);
  return RefineVisp(frame, rect, reference, frame_to_raster, options);
}

}  // namespace mosaicloc::tracking
