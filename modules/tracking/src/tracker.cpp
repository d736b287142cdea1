#include "mosaicloc/tracking/tracker.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Eigenvalues>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "mosaicloc/core/error.hpp"
#include "area_halve.hpp"
#include "render_window.hpp"

namespace mosaicloc::tracking {
namespace {

using Affine = Eigen::Matrix<double, 2, 3>;

Eigen::Vector2d CentreOf(const cv::Rect& r) { return {r.x + 0.5 * (r.width - 1), r.y + 0.5 * (r.height - 1)}; }

}  // namespace

bool TrackerOptions::Check(std::string* why) const {
  auto fail = [why](const char* message) {
    if (why != nullptr) *why = message;
    return false;
  };
  if (!(search_sigmas >= 0.5 && search_sigmas <= 20.0)) return fail("search_sigmas must be in [0.5, 20]");
  if (spare_templates < 0 || spare_templates > 64) return fail("spare_templates must be in [0, 64]");
  if (min_search_px < 1) return fail("min_search_px must be >= 1");
  if (max_search_px < min_search_px || max_search_px > 4096) {
    return fail("max_search_px must be at least min_search_px and at most 4096");
  }
  if (!(min_peak > -1.0 && min_peak < 1.0)) return fail("min_peak must be in (-1, 1)");
  if (!(max_ambiguity > 0.0 && max_ambiguity <= 1.0)) return fail("max_ambiguity must be in (0, 1]");
  if (!(min_zncc > -1.0 && min_zncc < 1.0)) return fail("min_zncc must be in (-1, 1)");
  if (refine_passes < 0 || refine_passes > 5) return fail("refine_passes must be in [0, 5]");
  if (!(min_window_mapped > 0.0 && min_window_mapped <= 1.0)) return fail("min_window_mapped must be in (0, 1]");
  // The parts last, so that a complaint about a field of this struct is not hidden by one of theirs.
  return templates.Check(why) && search.Check(why) && refine.Check(why) && solver.Check(why);
}

const char* ToString(TrackFailure failure) {
  switch (failure) {
    case TrackFailure::kNone: return "ok";
    case TrackFailure::kNoTexture: return "no texture";
    case TrackFailure::kOffMap: return "off map";
    case TrackFailure::kAmbiguous: return "ambiguous";
    case TrackFailure::kNoMatch: return "no match";
    case TrackFailure::kTooFewInliers: return "too few inliers";
    case TrackFailure::kNotConverged: return "not converged";
  }
  return "unknown";
}

Tracker::Tracker(const camera::IdealCamera& camera, const TrackerOptions& options)
    : camera_(camera), options_(options) {
  std::string why;
  if (!options_.Check(&why)) core::ThrowInvalidInput("tracker options: " + why);
}

TrackResult Tracker::Track(const cv::Mat& frame, const core::Pose2& prior, const Eigen::Matrix3d& prior_covariance,
                           const ReferenceRaster& reference) const {
  TrackResult result;
  result.world_from_camera = prior;
  auto fail = [&result](TrackFailure failure, std::string reason) {
    result.failure = failure;
    result.reason = std::move(reason);
    return result;
  };
  if (frame.empty() || frame.type() != CV_8UC1 || frame.cols != camera_.width_px() ||
      frame.rows != camera_.height_px()) {
    return fail(TrackFailure::kNoTexture, "the frame is not an 8-bit " + std::to_string(camera_.width_px()) + "x" +
                                              std::to_string(camera_.height_px()) + " image");
  }
  thread_local cv::Mat half;  // reused frame to frame: no page faults for a fresh buffer
  detail::HalveImage(frame, half);
  std::vector<TemplateSpot> spots = SelectTemplates(frame, half, options_.templates);
  if (spots.empty()) return fail(TrackFailure::kNoTexture, "no template of the frame has enough texture");
  const std::size_t wanted = spots.size();
  // Spare templates, chosen only when the coarse search rejects some of the first ones
  // (ambiguous, off the map): a finer grid, most textured first, away from those tried.
  bool spares_added = options_.templates.mode != TemplateMode::kSpread || options_.spare_templates == 0;
  const auto add_spares = [&] {
    spares_added = true;
    TemplateOptions more = options_.templates;
    more.count += options_.spare_templates;
    std::vector<TemplateSpot> extra = SelectTemplates(frame, half, more);
    std::stable_sort(extra.begin(), extra.end(),
                     [](const TemplateSpot& a, const TemplateSpot& b) { return a.texture > b.texture; });
    const std::size_t tried = spots.size();
    for (const TemplateSpot& candidate : extra) {
      bool overlaps = false;
      for (std::size_t i = 0; i < tried && !overlaps; ++i) {
        overlaps = (candidate.rect & spots[i].rect).area() * 2 > candidate.rect.area();
      }
      if (!overlaps) spots.push_back(candidate);
    }
  };

  const Affine world_to_raster = reference.WorldToRaster();
  const Affine raster_to_world = reference.RasterToWorld();
  const double raster_mm = reference.mm_per_px();
  const double s = camera_.mm_per_px();
  const Eigen::Vector2d image_centre(camera_.cx(), camera_.cy());
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> position_eigen(prior_covariance.topLeftCorner<2, 2>());
  const double sigma_position_px = std::sqrt(std::max(position_eigen.eigenvalues().maxCoeff(), 0.0)) / s;
  const double sigma_yaw = std::sqrt(std::max(prior_covariance(2, 2), 0.0));

  // Coarse: each template searched around its predicted place at half resolution (the
  // reference's next level against the frame's 2x2 average), in a window rendered in the
  // frame's orientation. Half-pixel accuracy there is all the refinement needs, at a quarter
  // of the cost, and the averaging keeps a degree of rotation from decorrelating fine detail.
  std::unique_ptr<const ReferenceRaster> coarser = reference.Coarser();
  const bool use_half = coarser != nullptr;
  const ReferenceRaster& search_reference = use_half ? *coarser : reference;
  const cv::Mat& search_frame = use_half ? half : frame;
  const int scale = use_half ? 2 : 1;
  // Search-frame pixel -> frame pixel: p = scale q + (scale - 1) / 2.
  Affine search_to_frame;
  search_to_frame << scale, 0.0, 0.5 * (scale - 1), 0.0, scale, 0.5 * (scale - 1);
  const Affine prior_to_raster = ComposeAffine(search_reference.WorldToRaster(),
                                               ComposeAffine(camera_.PixelToWorldAffine(prior), search_to_frame));
  const Affine search_raster_to_world = search_reference.RasterToWorld();
  std::vector<Correspondence> coarse;
  std::vector<std::size_t> coarse_template;
  int off_map = 0, ambiguous = 0;
  // Searches templates in order (spares when the first ones run out) until `target` have a
  // coarse match; resumable, so the refinement can ask for more.
  std::size_t next_spot = 0;
  const auto search_until = [&](std::size_t target) {
    for (; next_spot < spots.size() || !spares_added; ++next_spot) {
      if (next_spot == spots.size()) {
        if (coarse.size() >= target) break;
        add_spares();
        if (next_spot == spots.size()) break;
      }
      if (coarse.size() >= target) break;
      const TemplateSpot spot = spots[next_spot];
      TemplateReport report;
      report.spot = spot;
      const Eigen::Vector2d centre = CentreOf(spot.rect);
      const double sigma_px = sigma_position_px + sigma_yaw * (centre - image_centre).norm();
      const int range = std::clamp(static_cast<int>(std::ceil(options_.search_sigmas * sigma_px)) + 1,
                                   options_.min_search_px, options_.max_search_px);
      report.search_range_px = range;
      const cv::Rect rect(spot.rect.x / scale, spot.rect.y / scale, spot.rect.width / scale, spot.rect.height / scale);
      const int search_range = (range + scale - 1) / scale + 1;
      const cv::Point origin(rect.x - search_range, rect.y - search_range);
      cv::Mat mask;
      bool all_known = false;
      cv::Mat window = detail::RenderWindowKnown(
          search_reference, prior_to_raster, origin,
          cv::Size(rect.width + 2 * search_range, rect.height + 2 * search_range), &mask, &all_known);
      if (!all_known) {
        const int known = cv::countNonZero(mask);
        // The template's predicted footprint must be mapped as the refinement will demand.
        const cv::Mat footprint = mask(cv::Rect(search_range, search_range, rect.width, rect.height));
        const double footprint_mapped =
            static_cast<double>(cv::countNonZero(footprint)) / static_cast<double>(footprint.total());
        if (static_cast<double>(known) < options_.min_window_mapped * static_cast<double>(mask.total()) ||
            footprint_mapped < options_.refine.min_mapped_fraction) {
          report.rejected = "off map";
          report.off_map = true;
          ++off_map;
          result.templates.push_back(std::move(report));
          continue;
        }
        if (known < static_cast<int>(mask.total())) window.setTo(cv::mean(window, mask), ~mask);
      }
      report.coarse = SearchZncc(search_frame(rect), window, options_.search);
      if (!report.coarse.found || report.coarse.peak < options_.min_peak) {
        report.rejected = "no match";
      } else if (report.coarse.ambiguity > options_.max_ambiguity) {
        report.rejected = "ambiguous";
        ++ambiguous;
      } else {
        // Window pixel (offset + template centre) shows the raster point the centre matches.
        const Eigen::Vector2d local = report.coarse.offset_px + 0.5 * Eigen::Vector2d(rect.width - 1, rect.height - 1);
        const Eigen::Vector2d search_px = Eigen::Vector2d(origin.x, origin.y) + local;
        Correspondence c;
        c.camera_mm = camera_.PixelToCamera(centre);
        c.world_mm = ApplyAffine(search_raster_to_world, ApplyAffine(prior_to_raster, search_px));
        c.sigma_mm = 0.3 * scale * s;
        coarse.push_back(c);
        coarse_template.push_back(result.templates.size());
      }
      result.templates.push_back(std::move(report));
    }
  };
  search_until(wanted);
  if (coarse.empty()) {
    if (off_map > 0 && off_map >= static_cast<int>(result.templates.size()) / 2 + 1) {
      return fail(TrackFailure::kOffMap, std::to_string(off_map) + " of " + std::to_string(result.templates.size()) +
                                             " templates fall outside the map");
    }
    if (ambiguous > 0) {
      return fail(TrackFailure::kAmbiguous, std::to_string(ambiguous) + " templates match in several places");
    }
    return fail(TrackFailure::kNoMatch, "no template was found in its search window");
  }

  // Coarse pose. Its outlier threshold is set by the coarse accuracy (a pixel or two).
  PoseSolverOptions coarse_solver = options_.solver;
  coarse_solver.loss_scale_mm = std::max(options_.solver.loss_scale_mm, 1.0 * scale * s);
  coarse_solver.outlier_threshold_mm = std::max(options_.solver.outlier_threshold_mm, 3.0 * scale * s);
  coarse_solver.min_inliers = std::min(options_.solver.min_inliers, static_cast<int>(coarse.size()));
  // With refinement the coarse pose only seeds it: the result's covariance is the fine one's.
  coarse_solver.compute_covariance = options_.refine_passes == 0;
  if (static_cast<int>(coarse.size()) < options_.solver.min_inliers && options_.refine_passes > 0) {
    return fail(TrackFailure::kTooFewInliers, std::to_string(coarse.size()) + " usable templates, " +
                                                  std::to_string(options_.solver.min_inliers) + " needed");
  }
  PoseSolution pose = SolvePlanarPose(coarse, prior, coarse_solver);
  if (!pose.ok()) return fail(TrackFailure::kTooFewInliers, std::string("coarse pose: ") + ToString(pose.failure));

  std::vector<std::size_t> used = coarse_template;
  for (std::size_t i = 0; i < used.size(); ++i) result.templates[used[i]].inlier = pose.inlier[i];
  for (int pass = 0; pass < options_.refine_passes; ++pass) {
    const Affine frame_to_raster = ComposeAffine(world_to_raster, camera_.PixelToWorldAffine(pose.world_from_camera));
    std::vector<Correspondence> fine;
    std::vector<std::size_t> fine_template;
    const auto refine = [&](std::size_t index) {
      TemplateReport& report = result.templates[index];
      report.refined = RefineTemplate(frame, report.spot.rect, reference, frame_to_raster, options_.refine);
      if (!report.refined.ok()) {
        report.rejected = std::string("refinement ") + ToString(report.refined.failure);
        report.off_map = report.refined.failure == RefineFailure::kOffMap;
        return;
      }
      if (report.refined.zncc < options_.min_zncc) {
        report.rejected = "weak match";
        return;
      }
      report.rejected.clear();
      Correspondence c;
      c.camera_mm = camera_.PixelToCamera(CentreOf(report.spot.rect));
      c.world_mm = ApplyAffine(raster_to_world, report.refined.centre_raster);
      c.sigma_mm = std::sqrt(0.5 * report.refined.covariance_px2.trace()) * raster_mm;
      fine.push_back(c);
      fine_template.push_back(index);
    };
    for (const std::size_t index : used) refine(index);
    // Too few survived refinement: search and refine further templates while there are any.
    while (static_cast<int>(fine.size()) < options_.solver.min_inliers) {
      const std::size_t before = coarse_template.size();
      search_until(coarse.size() + static_cast<std::size_t>(options_.solver.min_inliers) - fine.size());
      if (coarse_template.size() == before) break;
      for (std::size_t i = before; i < coarse_template.size(); ++i) refine(coarse_template[i]);
    }
    if (static_cast<int>(fine.size()) < options_.solver.min_inliers) {
      return fail(TrackFailure::kTooFewInliers, std::to_string(fine.size()) + " templates refined, " +
                                                    std::to_string(options_.solver.min_inliers) + " needed");
    }
    PoseSolution refined = SolvePlanarPose(fine, pose.world_from_camera, options_.solver);
    if (!refined.ok()) {
      return fail(refined.failure == PoseFailure::kNotConverged ? TrackFailure::kNotConverged
                                                                : TrackFailure::kTooFewInliers,
                  std::string("pose: ") + ToString(refined.failure));
    }
    for (std::size_t i = 0; i < fine_template.size(); ++i) {
      result.templates[fine_template[i]].inlier = refined.inlier[i];
      if (!refined.inlier[i]) result.templates[fine_template[i]].rejected = "outlier";
    }
    // Each template's translation absorbs a change of position; only a change of yaw alters
    // the linearisation, by turning the template against the reference about its centre.
    double radius_px = 0.0;
    for (const std::size_t index : fine_template) {
      const cv::Rect& r = result.templates[index].spot.rect;
      radius_px = std::max(radius_px, 0.5 * std::hypot(r.width, r.height));
    }
    const double turned_px =
        std::abs(YawDifference(refined.world_from_camera, pose.world_from_camera)) * radius_px;
    pose = std::move(refined);
    used = fine_template;
    if (turned_px < options_.repeat_below_px) break;
  }

  if (std::isinf(pose.covariance(2, 2))) {
    return fail(TrackFailure::kTooFewInliers, std::to_string(pose.inliers) +
                                                  " inlier templates at one place: the yaw is not determined");
  }
  result.world_from_camera = pose.world_from_camera;
  result.covariance = pose.covariance;
  result.inliers = pose.inliers;
  result.rms_residual_mm = pose.rms_residual_mm;
  double zncc_sum = 0.0;
  int zncc_count = 0;
  for (const TemplateReport& report : result.templates) {
    if (!report.inlier) continue;
    zncc_sum += options_.refine_passes > 0 ? report.refined.zncc : report.coarse.peak;
    ++zncc_count;
  }
  result.mean_zncc = zncc_count > 0 ? zncc_sum / zncc_count : 0.0;
  return result;
}

TrackResult RegisterFrames(const Tracker& tracker, const cv::Mat& previous, const cv::Mat& current,
                           const core::Pose2& prior_previous_from_current, const Eigen::Matrix3d& prior_covariance) {
  const ImageReference reference(previous, core::Pose2::Identity(), tracker.camera().mm_per_px());
  return tracker.Track(current, prior_previous_from_current, prior_covariance, reference);
}

}  // namespace mosaicloc::tracking
