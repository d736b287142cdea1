#include "mosaicloc/tracking/tracker.hpp"

#include <algorithm>
#include <cmath>
#include <memory>
#include <utility>
#include <vector>

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

// One call of Tracker::Track, its state an object and its steps the methods, in the order Run
// takes them: select the frame's templates; search them coarsely, each around its predicted
// place (spares when the first ones are rejected); solve a coarse pose from the matches;
// refine the templates against it and solve again, a few rounds (searching more templates when
// too few survive the refinement); report the pose.
class FrameRegistration {
 public:
  FrameRegistration(const camera::IdealCamera& camera, const TrackerOptions& options, const cv::Mat& frame,
                    const core::Pose2& prior, const Eigen::Matrix3d& prior_covariance,
                    const ReferenceRaster& reference, double prior_scale, const PreparedFrame* prepared = nullptr)
      : prepared_(prepared),
        calibrated_(camera),
        camera_(camera.Scaled(prior_scale)),
        view_scale_(prior_scale),
        options_(options),
        frame_(frame),
        prior_(prior),
        prior_covariance_(prior_covariance),
        reference_(reference),
        world_to_raster_(reference.WorldToRaster()),
        raster_to_world_(reference.RasterToWorld()),
        raster_mm_(reference.mm_per_px()) {
    result_.world_from_camera = prior;
  }

  TrackResult Run() {
    // Each step returns false when it failed the frame, and says why in the result.
    const bool registered =
        FrameFits() && SelectSpots() && SearchCoarsely() && SolveCoarsePose() && Refine() && YawDetermined();
    if (registered) Report();
    return std::move(result_);
  }

 private:
  // Records why the frame gets no fix; false, for the steps to return.
  bool Fail(TrackFailure failure, std::string reason) {
    result_.failure = failure;
    result_.reason = std::move(reason);
    return false;
  }

  bool FrameFits() {
    if (frame_.empty() || frame_.type() != CV_8UC1 || frame_.cols != camera_.width_px() ||
        frame_.rows != camera_.height_px()) {
      return Fail(TrackFailure::kNoTexture, "the frame is not an 8-bit " + std::to_string(camera_.width_px()) + "x" +
                                                std::to_string(camera_.height_px()) + " image");
    }
    return true;
  }

  // The frame's templates, and its 2x2 average for the coarse search.
  bool SelectSpots() {
    if (prepared_ != nullptr) {
      half_ = &prepared_->half;
      spots_ = prepared_->spots;
    } else {
      thread_local cv::Mat half;  // reused frame to frame: no page faults for a fresh buffer
      detail::HalveImage(frame_, half);
      half_ = &half;
      spots_ = SelectTemplates(frame_, half, options_.templates);
    }
    if (spots_.empty()) return Fail(TrackFailure::kNoTexture, "no template of the frame has enough texture");
    wanted_ = spots_.size();
    spares_added_ = options_.templates.mode != TemplateMode::kSpread || options_.spare_templates == 0;
    return true;
  }

  // Spare templates, chosen only when the coarse search rejects some of the first ones
  // (ambiguous, off the map): a finer grid, most textured first, away from those tried.
  void AddSpares() {
    spares_added_ = true;
    TemplateOptions more = options_.templates;
    more.count += options_.spare_templates;
    std::vector<TemplateSpot> extra = SelectTemplates(frame_, *half_, more);
    std::stable_sort(extra.begin(), extra.end(),
                     [](const TemplateSpot& a, const TemplateSpot& b) { return a.texture > b.texture; });
    const std::size_t tried = spots_.size();
    for (const TemplateSpot& candidate : extra) {
      bool overlaps = false;
      for (std::size_t i = 0; i < tried && !overlaps; ++i) {
        overlaps = (candidate.rect & spots_[i].rect).area() * 2 > candidate.rect.area();
      }
      if (!overlaps) spots_.push_back(candidate);
    }
  }

  // Coarse: each template searched around its predicted place at half resolution (the
  // reference's next level against the frame's 2x2 average), in a window rendered in the
  // frame's orientation. Half-pixel accuracy there is all the refinement needs, at a quarter
  // of the cost, and the averaging keeps a degree of rotation from decorrelating fine detail.
  void PrepareCoarseSearch() {
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> position_eigen(prior_covariance_.topLeftCorner<2, 2>());
    sigma_position_px_ = std::sqrt(std::max(position_eigen.eigenvalues().maxCoeff(), 0.0)) / camera_.mm_per_px();
    sigma_yaw_ = std::sqrt(std::max(prior_covariance_(2, 2), 0.0));
    coarser_ = reference_.Coarser();
    const bool use_half = coarser_ != nullptr;
    search_reference_ = use_half ? coarser_.get() : &reference_;
    search_frame_ = use_half ? half_ : &frame_;
    scale_ = use_half ? 2 : 1;
    // Search-frame pixel -> frame pixel: p = scale q + (scale - 1) / 2.
    Affine search_to_frame;
    search_to_frame << scale_, 0.0, 0.5 * (scale_ - 1), 0.0, scale_, 0.5 * (scale_ - 1);
    prior_to_raster_ = ComposeAffine(search_reference_->WorldToRaster(),
                                     ComposeAffine(camera_.PixelToWorldAffine(prior_), search_to_frame));
    search_raster_to_world_ = search_reference_->RasterToWorld();
  }

  // Searches templates in order (spares when the first ones run out) until `target` have a
  // coarse match; resumable, so the refinement can ask for more.
  void SearchUntil(std::size_t target) {
    for (; next_spot_ < spots_.size() || !spares_added_; ++next_spot_) {
      if (next_spot_ == spots_.size()) {
        if (coarse_.size() >= target) break;
        AddSpares();
        if (next_spot_ == spots_.size()) break;
      }
      if (coarse_.size() >= target) break;
      SearchTemplate(spots_[next_spot_]);
    }
  }

  // One template's coarse search; a match becomes a coarse correspondence.
  void SearchTemplate(const TemplateSpot& spot) {
    const double s = camera_.mm_per_px();
    const Eigen::Vector2d image_centre(camera_.cx(), camera_.cy());
    TemplateReport report;
    report.spot = spot;
    const Eigen::Vector2d centre = CentreOf(spot.rect);
    const double sigma_px = sigma_position_px_ + sigma_yaw_ * (centre - image_centre).norm();
    const int range = std::clamp(static_cast<int>(std::ceil(options_.search_sigmas * sigma_px)) + 1,
                                 options_.min_search_px, options_.max_search_px);
    report.search_range_px = range;
    const cv::Rect rect(spot.rect.x / scale_, spot.rect.y / scale_, spot.rect.width / scale_,
                        spot.rect.height / scale_);
    const int search_range = (range + scale_ - 1) / scale_ + 1;
    const cv::Point origin(rect.x - search_range, rect.y - search_range);
    cv::Mat mask;
    bool all_known = false;
    cv::Mat window = detail::RenderWindowKnown(
        *search_reference_, prior_to_raster_, origin,
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
        ++off_map_;
        result_.templates.push_back(std::move(report));
        return;
      }
      if (known < static_cast<int>(mask.total())) window.setTo(cv::mean(window, mask), ~mask);
    }
    report.coarse = SearchZncc((*search_frame_)(rect), window, options_.search);
    if (!report.coarse.found || report.coarse.peak < options_.min_peak) {
      report.rejected = "no match";
    } else if (report.coarse.ambiguity > options_.max_ambiguity) {
      report.rejected = "ambiguous";
      ++ambiguous_;
    } else {
      // Window pixel (offset + template centre) shows the raster point the centre matches.
      const Eigen::Vector2d local = report.coarse.offset_px + 0.5 * Eigen::Vector2d(rect.width - 1, rect.height - 1);
      const Eigen::Vector2d search_px = Eigen::Vector2d(origin.x, origin.y) + local;
      Correspondence c;
      c.camera_mm = camera_.PixelToCamera(centre);
      c.world_mm = ApplyAffine(search_raster_to_world_, ApplyAffine(prior_to_raster_, search_px));
      c.sigma_mm = 0.3 * scale_ * s;
      coarse_.push_back(c);
      coarse_template_.push_back(result_.templates.size());
    }
    result_.templates.push_back(std::move(report));
  }

  // The first `wanted_` coarse matches; when there are none, why, from what the search saw.
  bool SearchCoarsely() {
    PrepareCoarseSearch();
    SearchUntil(wanted_);
    if (!coarse_.empty()) return true;
    if (off_map_ > 0 && off_map_ >= static_cast<int>(result_.templates.size()) / 2 + 1) {
      return Fail(TrackFailure::kOffMap, std::to_string(off_map_) + " of " +
                                             std::to_string(result_.templates.size()) +
                                             " templates fall outside the map");
    }
    if (ambiguous_ > 0) {
      return Fail(TrackFailure::kAmbiguous, std::to_string(ambiguous_) + " templates match in several places");
    }
    return Fail(TrackFailure::kNoMatch, "no template was found in its search window");
  }

  // Coarse pose. Its outlier threshold is set by the coarse accuracy (a pixel or two).
  bool SolveCoarsePose() {
    const double s = camera_.mm_per_px();
    PoseSolverOptions coarse_solver = options_.solver;
    coarse_solver.loss_scale_mm = std::max(options_.solver.loss_scale_mm, 1.0 * scale_ * s);
    coarse_solver.outlier_threshold_mm = std::max(options_.solver.outlier_threshold_mm, 3.0 * scale_ * s);
    coarse_solver.min_inliers = std::min(options_.solver.min_inliers, static_cast<int>(coarse_.size()));
    // With refinement the coarse pose only seeds it: the result's covariance is the fine one's.
    coarse_solver.compute_covariance = options_.refine_passes == 0;
    // A pixel or two of accuracy does not show a tilt; the refined templates do.
    coarse_solver.estimate_tilt = options_.refine_passes == 0 && options_.solver.estimate_tilt;
    coarse_solver.camera_height_mm = options_.solver.camera_height_mm * view_scale_;
    if (static_cast<int>(coarse_.size()) < options_.solver.min_inliers && options_.refine_passes > 0) {
      return Fail(TrackFailure::kTooFewInliers, std::to_string(coarse_.size()) + " usable templates, " +
                                                    std::to_string(options_.solver.min_inliers) + " needed");
    }
    pose_ = SolvePlanarPose(coarse_, prior_, coarse_solver);
    if (!pose_.ok()) return Fail(TrackFailure::kTooFewInliers, std::string("coarse pose: ") + ToString(pose_.failure));
    Rescale(pose_);
    used_ = coarse_template_;
    for (std::size_t i = 0; i < used_.size(); ++i) result_.templates[used_[i]].inlier = pose_.inlier[i];
    return true;
  }

  // Rounds of refinement, each re-linearised around the latest pose, until a round turns the
  // templates by less than repeat_below_px.
  bool Refine() {
    for (int pass = 0; pass < options_.refine_passes; ++pass) {
      bool turned = false;
      if (!RefinePass(&turned)) return false;
      if (!turned) break;
    }
    return true;
  }

  // One round: the templates of the latest pose refined against it (more searched when too
  // few survive) and the pose solved from them. `*turned`: the yaw changed enough to repeat.
  bool RefinePass(bool* turned) {
    const Affine frame_to_raster =
        ComposeAffine(world_to_raster_, camera_.PixelToWorldAffine(pose_.world_from_camera));
    fine_.clear();
    fine_template_.clear();
    for (const std::size_t index : used_) RefineTemplateAt(index, frame_to_raster);
    // Too few survived refinement: search and refine further templates while there are any.
    while (static_cast<int>(fine_.size()) < options_.solver.min_inliers) {
      const std::size_t before = coarse_template_.size();
      SearchUntil(coarse_.size() + static_cast<std::size_t>(options_.solver.min_inliers) - fine_.size());
      if (coarse_template_.size() == before) break;
      for (std::size_t i = before; i < coarse_template_.size(); ++i) {
        RefineTemplateAt(coarse_template_[i], frame_to_raster);
      }
    }
    if (static_cast<int>(fine_.size()) < options_.solver.min_inliers) {
      return Fail(TrackFailure::kTooFewInliers, std::to_string(fine_.size()) + " templates refined, " +
                                                    std::to_string(options_.solver.min_inliers) + " needed");
    }
    // The correspondences' camera_mm are at the height the view is rendered for.
    PoseSolverOptions solver = options_.solver;
    solver.camera_height_mm = options_.solver.camera_height_mm * view_scale_;
    PoseSolution refined = SolvePlanarPose(fine_, pose_.world_from_camera, solver);
    if (!refined.ok()) {
      return Fail(refined.failure == PoseFailure::kNotConverged ? TrackFailure::kNotConverged
                                                                : TrackFailure::kTooFewInliers,
                  std::string("pose: ") + ToString(refined.failure));
    }
    for (std::size_t i = 0; i < fine_template_.size(); ++i) {
      result_.templates[fine_template_[i]].inlier = refined.inlier[i];
      if (!refined.inlier[i]) result_.templates[fine_template_[i]].rejected = "outlier";
    }
    // Each template's translation absorbs a change of position; only a change of yaw or of
    // scale alters the linearisation, by turning or stretching the template against the
    // reference about its centre.
    double radius_px = 0.0;
    for (const std::size_t index : fine_template_) {
      const cv::Rect& r = result_.templates[index].spot.rect;
      radius_px = std::max(radius_px, 0.5 * std::hypot(r.width, r.height));
    }
    const double turned_px =
        (std::abs(YawDifference(refined.world_from_camera, pose_.world_from_camera)) + std::abs(refined.scale - 1.0)) *
        radius_px;
    Rescale(refined);
    pose_ = std::move(refined);
    used_ = fine_template_;
    *turned = !(turned_px < options_.repeat_below_px);
    return true;
  }

  // Template `index` refined against the reference at frame_to_raster; a good match becomes
  // a fine correspondence.
  void RefineTemplateAt(std::size_t index, const Affine& frame_to_raster) {
    TemplateReport& report = result_.templates[index];
    // An inlier of the coarse pose is one of the fix's only if it is refined and used again.
    report.inlier = false;
    report.refined = RefineTemplate(frame_, report.spot.rect, reference_, frame_to_raster, options_.refine);
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
    c.world_mm = ApplyAffine(raster_to_world_, report.refined.centre_raster);
    c.sigma_mm = std::sqrt(0.5 * report.refined.covariance_px2.trace()) * raster_mm_;
    fine_.push_back(c);
    fine_template_.push_back(index);
  }

  // The camera at the scale a solve found (relative to the one its correspondences used).
  void Rescale(const PoseSolution& solution) {
    if (!solution.scale_estimated) return;
    view_scale_ *= solution.scale;
    camera_ = calibrated_.Scaled(view_scale_);
  }

  bool YawDetermined() {
    if (std::isinf(pose_.covariance(2, 2))) {
      return Fail(TrackFailure::kTooFewInliers, std::to_string(pose_.inliers) +
                                                    " inlier templates at one place: the yaw is not determined");
    }
    return true;
  }

  void Report() {
    result_.world_from_camera = pose_.world_from_camera;
    result_.covariance = pose_.covariance;
    result_.inliers = pose_.inliers;
    result_.rms_residual_mm = pose_.rms_residual_mm;
    // The last solve's scale is relative to view_scale_ before it was applied, so its
    // standard deviation scales with view_scale_ after.
    result_.scale = view_scale_;
    result_.scale_estimated = pose_.scale_estimated;
    if (pose_.scale_estimated) result_.scale_sigma = view_scale_ * pose_.scale_sigma;
    result_.tilt_estimated = pose_.tilt_estimated;
    result_.tilt_x_rad = pose_.tilt_x_rad;
    result_.tilt_y_rad = pose_.tilt_y_rad;
    result_.tilt_sigma_rad = pose_.tilt_sigma_rad;
    double zncc_sum = 0.0;
    int zncc_count = 0;
    for (const TemplateReport& report : result_.templates) {
      if (!report.inlier) continue;
      zncc_sum += options_.refine_passes > 0 ? report.refined.zncc : report.coarse.peak;
      ++zncc_count;
    }
    result_.mean_zncc = zncc_count > 0 ? zncc_sum / zncc_count : 0.0;
  }

  const PreparedFrame* prepared_;  // the frame's half image and templates, made before; or null
  const camera::IdealCamera& calibrated_;
  camera::IdealCamera camera_;  // at view_scale_
  double view_scale_ = 1.0;
  const TrackerOptions& options_;
  const cv::Mat& frame_;
  const core::Pose2& prior_;
  const Eigen::Matrix3d& prior_covariance_;
  const ReferenceRaster& reference_;
  const Affine world_to_raster_, raster_to_world_;
  const double raster_mm_;
  TrackResult result_;

  // The templates: the first `wanted_`, then spares.
  const cv::Mat* half_ = nullptr;  // the frame's 2x2 average
  std::vector<TemplateSpot> spots_;
  std::size_t wanted_ = 0;
  bool spares_added_ = false;

  // The coarse search: where it looks, and what it found so far.
  double sigma_position_px_ = 0.0, sigma_yaw_ = 0.0;
  std::unique_ptr<const ReferenceRaster> coarser_;
  const ReferenceRaster* search_reference_ = nullptr;
  const cv::Mat* search_frame_ = nullptr;
  int scale_ = 1;
  Affine prior_to_raster_ = Affine::Zero();
  Affine search_raster_to_world_ = Affine::Zero();
  std::size_t next_spot_ = 0;
  std::vector<Correspondence> coarse_;
  std::vector<std::size_t> coarse_template_;  // the template of each coarse correspondence
  int off_map_ = 0, ambiguous_ = 0;

  // The refinement: the latest pose, the templates it rests on, and the current round's matches.
  PoseSolution pose_;
  std::vector<std::size_t> used_;
  std::vector<Correspondence> fine_;
  std::vector<std::size_t> fine_template_;
};
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

namespace {

// The tracker's options with a predicted tilt held where it is not estimated.
TrackerOptions Holding(const TrackerOptions& options, const TiltPrediction& tilt) {
  TrackerOptions held = options;
  held.solver.held_tilt_x_rad = tilt.x_rad;
  held.solver.held_tilt_y_rad = tilt.y_rad;
  held.solver.held_tilt_sigma_rad = tilt.sigma_rad;
  return held;
}

bool Level(const TiltPrediction& tilt) { return tilt.x_rad == 0.0 && tilt.y_rad == 0.0 && tilt.sigma_rad == 0.0; }

}  // namespace

TrackResult Tracker::Track(const cv::Mat& frame, const core::Pose2& prior, const Eigen::Matrix3d& prior_covariance,
                           const ReferenceRaster& reference, double prior_scale, const TiltPrediction& prior_tilt) const {
  if (Level(prior_tilt)) {
    return FrameRegistration(camera_, options_, frame, prior, prior_covariance, reference, prior_scale).Run();
  }
  const TrackerOptions held = Holding(options_, prior_tilt);
  return FrameRegistration(camera_, held, frame, prior, prior_covariance, reference, prior_scale).Run();
}

TrackResult Tracker::Track(const PreparedFrame& frame, const core::Pose2& prior, const Eigen::Matrix3d& prior_covariance,
                           const ReferenceRaster& reference, double prior_scale, const TiltPrediction& prior_tilt) const {
  if (Level(prior_tilt)) {
    return FrameRegistration(camera_, options_, frame.image, prior, prior_covariance, reference, prior_scale, &frame)
        .Run();
  }
  const TrackerOptions held = Holding(options_, prior_tilt);
  return FrameRegistration(camera_, held, frame.image, prior, prior_covariance, reference, prior_scale, &frame).Run();
}

PreparedFrame Tracker::Prepare(const cv::Mat& frame) const {
  PreparedFrame prepared;
  prepared.image = frame;
  // A frame Track would refuse keeps no half image or templates: Track says why.
  if (frame.empty() || frame.type() != CV_8UC1 || frame.cols != camera_.width_px() || frame.rows != camera_.height_px()) {
    return prepared;
  }
  detail::HalveImage(frame, prepared.half);
  prepared.spots = SelectTemplates(frame, prepared.half, options_.templates);
  return prepared;
}

TrackResult RegisterFrames(const Tracker& tracker, const cv::Mat& previous, const cv::Mat& current,
                           const core::Pose2& prior_previous_from_current, const Eigen::Matrix3d& prior_covariance) {
  const ImageReference reference(previous, core::Pose2::Identity(), tracker.camera().mm_per_px());
  return tracker.Track(current, prior_previous_from_current, prior_covariance, reference);
}

TrackResult RegisterFrames(const Tracker& tracker, const PreparedFrame& previous, const PreparedFrame& current,
                           const core::Pose2& prior_previous_from_current, const Eigen::Matrix3d& prior_covariance) {
  const ImageReference reference(previous.image, core::Pose2::Identity(), tracker.camera().mm_per_px(), previous.half);
  return tracker.Track(current, prior_previous_from_current, prior_covariance, reference);
}

}  // namespace mosaicloc::tracking
