#pragma once

#include <string>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include "mosaicloc/tracking/reference.hpp"

namespace mosaicloc::tracking {

/// Sub-pixel refinement of one template against the reference.
enum class RefineMethod {
  /// Our inverse-compositional Gauss-Newton on the translation of the template in the
  /// reference raster, with ZNCC normalisation (insensitive to gain and offset). It samples
  /// the stored raster directly, so no intermediate rendering blurs or quantises it.
  kDirect,
  kVispSsd,   ///< ViSP vpTemplateTrackerSSDInverseCompositional
  kVispZncc,  ///< ViSP vpTemplateTrackerZNCCInverseCompositional
};
/// Warp estimated by the ViSP methods (kDirect is always a translation: rotation is handled
/// by the pose solver across templates).
enum class RefineWarp { kTranslation, kSrt, kHomography };
/// The names the localizer configuration uses: "direct", "visp-ssd", "visp-zncc"; and
/// "translation", "srt", "homography".
const char* ToString(RefineMethod method);
const char* ToString(RefineWarp warp);
inline constexpr RefineMethod kRefineMethods[] = {RefineMethod::kDirect, RefineMethod::kVispSsd, RefineMethod::kVispZncc};
inline constexpr RefineWarp kRefineWarps[] = {RefineWarp::kTranslation, RefineWarp::kSrt, RefineWarp::kHomography};

struct RefineOptions {
  RefineMethod method = RefineMethod::kDirect;
  RefineWarp warp = RefineWarp::kTranslation;
  int max_iterations = 20;
  /// Stop when an update moves the template by less than this, px.
  double tolerance_px = 1e-3;
  /// Largest correction accepted, px: beyond it the refinement is reported as diverged.
  double max_shift_px = 8.0;
  /// Use every `sampling`-th pixel in both directions (ViSP: setSampling(n, n)).
  int sampling = 2;
  /// ViSP pyramid levels; > 1 when the coarse error can exceed a few pixels.
  int visp_pyramid_levels = 1;
  /// Gaussian low-pass (sigma, px) applied alike to the template and the reference before
  /// kDirect refinement; 0 = off. Keeps bilinear interpolation an accurate model on floors
  /// with pixel-scale detail.
  double prefilter_sigma_px = 1.0;
  /// Share of the template that must land on mapped reference pixels.
  double min_mapped_fraction = 0.9;
  /// kDirect: after the ZNCC fit, reweight the pixels by Tukey's biweight of their residual
  /// (iteratively reweighted least squares) so that parts of the template that look different
  /// from the map (joints and grout seen from another place in the view, a changed patch) stop
  /// pulling the fit; the covariance is the weighted one. false: plain least squares.
  bool robust = false;
  bool Check(std::string* why) const;
};

/// Why a refinement gave no match.
enum class RefineFailure { kNone, kOffMap, kDiverged, kNotConverged, kVispError };
const char* ToString(RefineFailure failure);

struct RefinedMatch {
  RefineFailure failure = RefineFailure::kNone;
  bool ok() const { return failure == RefineFailure::kNone; }
  /// Where the template's centre pixel lies in the reference raster (col, row), sub-pixel.
  Eigen::Vector2d centre_raster = Eigen::Vector2d::Zero();
  /// Covariance of centre_raster, raster px^2, from the Gauss-Newton information and the
  /// residual noise (kDirect); from the final ZNCC residual for the ViSP methods.
  Eigen::Matrix2d covariance_px2 = Eigen::Matrix2d::Identity();
  /// Rotation of the template found by the warp (ViSP SRT and homography), rad in the frame's
  /// pixel axes; 0 for the translation-only methods.
  double rotation_rad = 0.0;
  double zncc = 0.0;  ///< between the template and the reference at the solution
  int iterations = 0;
  std::string detail;  ///< e.g. ViSP's exception text
};

/// Refines the template `rect` of `frame` (CV_8UC1) against `reference`, starting from
/// `frame_to_raster` (2x3 affine: frame pixel -> reference raster (col, row)), the current
/// estimate of where the frame lies. Never throws for a failed match.
RefinedMatch RefineTemplate(const cv::Mat& frame, const cv::Rect& rect, const ReferenceRaster& reference,
                            const Eigen::Matrix<double, 2, 3>& frame_to_raster, const RefineOptions& options);

}  // namespace mosaicloc::tracking
