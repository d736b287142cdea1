#include "mosaicloc/tracking/relocalize.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <utility>

#include <Eigen/Cholesky>
#include <fmt/format.h>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/tracking/render_window.hpp"

namespace mosaicloc::tracking {
namespace {

// Adds a verified place to `verified`. Two candidates of one place verify to the same pose:
// it is kept once, with its better match.
void KeepVerified(std::vector<TrackResult>* verified, TrackResult r) {
  const auto same = std::find_if(verified->begin(), verified->end(), [&r](const TrackResult& v) {
    return Distance(v.world_from_camera, r.world_from_camera) < 2.0;
  });
  if (same == verified->end()) {
    verified->push_back(std::move(r));
  } else if (r.mean_zncc > same->mean_zncc) {
    *same = std::move(r);
  }
}

/// The templates a registration searched on the map (those that fell off it are not evidence).
int SearchedOnMap(const TrackResult& r) {
  return static_cast<int>(std::count_if(r.templates.begin(), r.templates.end(),
                                        [](const TemplateReport& t) { return !t.off_map; }));
}

/// "3 of 4 templates (ZNCC 0.91)": what a verified place rests on.
std::string InlierSummary(const TrackResult& r) {
  return fmt::format("{} of {} templates (ZNCC {:.2f})", r.inliers, SearchedOnMap(r), r.mean_zncc);
}

}  // namespace

bool RelocalizeOptions::Check(std::string* why) const {
  auto fail = [why](const char* message) {
    if (why != nullptr) *why = message;
    return false;
  };
  if (level < 1 || level > 6) return fail("relocalization level must be in [1, 6]");
  if (candidates < 1 || candidates > 50) return fail("relocalization candidates must be in [1, 50]");
  if (!(zncc_tie >= 0.0 && zncc_tie <= 1.0)) return fail("relocalization zncc_tie must be in [0, 1]");
  if (!(nearer_factor >= 1.0)) return fail("relocalization nearer_factor must be >= 1");
  if (!(min_coverage > 0.0 && min_coverage <= 1.0)) return fail("relocalization min_coverage must be in (0, 1]");
  if (whole_view_templates < 0 || whole_view_templates > 64) {
    return fail("relocalization whole_view_templates must be in [0, 64]");
  }
  if (!(min_inlier_share >= 0.0 && min_inlier_share <= 1.0)) return fail("relocalization min_inlier_share must be in [0, 1]");
  return true;
}

Relocalizer::Relocalizer(const Tracker& tracker, const ReferenceRaster& reference, const RelocalizeOptions& options)
    : tracker_(tracker), reference_(reference), options_(options) {
  std::string why;
  if (!options_.Check(&why)) core::ThrowInvalidInput("relocalization options: " + why);
  if (options_.whole_view_templates > 0) {
    TrackerOptions whole = tracker.options();
    whole.templates.mode = TemplateMode::kSpread;
    whole.templates.count = options_.whole_view_templates;
    whole_view_.emplace(tracker.camera(), whole);
  }
}

std::optional<TrackResult> Relocalizer::WholeView(const cv::Mat& frame, const TrackResult& place, double scale) const {
  if (!whole_view_) return place;
  // Around the place found: a template's search then reaches a few pixels.
  const Eigen::Matrix3d around = Eigen::Vector3d(0.25, 0.25, std::pow(0.2 * std::numbers::pi / 180.0, 2)).asDiagonal();
  TrackResult whole = whole_view_->Track(frame, place.world_from_camera, around, reference_, scale);
  if (!whole.ok() || whole.mean_zncc < options_.min_zncc) return std::nullopt;
  if (whole.inliers < options_.min_inlier_share * SearchedOnMap(whole)) return std::nullopt;
  return whole;
}

TrackResult Relocalizer::Search(const cv::Mat& frame, const core::Pose2& prior,
                                const Eigen::Matrix3d& prior_covariance, double radius_mm,
                                const std::optional<RelocalizeGate>& gate, double scale_prior) const {
  const camera::IdealCamera camera = tracker_.camera().Scaled(scale_prior);
  TrackResult none;
  none.failure = TrackFailure::kNoMatch;
  none.reason = "relocalization found no verified place";
  // The coarse level of the map, and the frame averaged down to it.
  const CoarseReference coarse = Coarsen(reference_, options_.level);
  const ReferenceRaster* level = coarse.raster;
  const int k = coarse.halvings;
  if (k == 0) return none;
  const int scale = 1 << k;
  cv::Mat small = frame;
  for (int i = 0; i < k; ++i) cv::resize(small, small, cv::Size(small.cols / 2, small.rows / 2), 0, 0, cv::INTER_AREA);

  // A window around the prediction in the frame's orientation: small-frame pixel q is frame
  // pixel scale q + (scale - 1) / 2.
  const int range = static_cast<int>(std::ceil(radius_mm / (camera.mm_per_px() * scale)));
  Eigen::Matrix<double, 2, 3> small_to_frame;
  small_to_frame << scale, 0.0, 0.5 * (scale - 1), 0.0, scale, 0.5 * (scale - 1);
  const Eigen::Matrix<double, 2, 3> small_to_raster =
      ComposeAffine(level->WorldToRaster(), ComposeAffine(camera.PixelToWorldAffine(prior), small_to_frame));
  cv::Mat mask;
  cv::Mat window = RenderWindow(*level, small_to_raster, cv::Point(-range, -range),
                                cv::Size(small.cols + 2 * range, small.rows + 2 * range), &mask);
  if (cv::countNonZero(mask) < small.cols * small.rows) return none;
  window.setTo(cv::mean(window, mask), ~mask);
  cv::Mat scores;
  cv::matchTemplate(window, small, scores, cv::TM_CCOEFF_NORMED);
  // Places where the frame fits only partly on the map are not candidates.
  cv::Mat coverage;
  cv::Mat mask_f;
  mask.convertTo(mask_f, CV_32F, 1.0 / 255.0);
  cv::boxFilter(mask_f, coverage, -1, small.size(), cv::Point(0, 0), true, cv::BORDER_CONSTANT);
  cv::Mat dilated;
  cv::dilate(scores, dilated, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(5, 5)));
  std::vector<std::pair<float, cv::Point>> peaks;
  for (int y = 0; y < scores.rows; ++y) {
    for (int x = 0; x < scores.cols; ++x) {
      const float v = scores.at<float>(y, x);
      if (v >= dilated.at<float>(y, x) && coverage.at<float>(y, x) >= options_.min_coverage) peaks.push_back({v, {x, y}});
    }
  }
  std::sort(peaks.begin(), peaks.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
  if (peaks.size() > static_cast<std::size_t>(options_.candidates)) {
    peaks.resize(static_cast<std::size_t>(options_.candidates));
  }
  // Verify every candidate at full resolution.
  const Eigen::Matrix3d candidate_covariance =
      Eigen::Vector3d(std::pow(2.0 * scale * camera.mm_per_px(), 2), std::pow(2.0 * scale * camera.mm_per_px(), 2),
                      prior_covariance(2, 2))
          .asDiagonal();
  std::vector<TrackResult> verified;
  for (const auto& [score, at] : peaks) {
    // The frame's centre moved by (at - range) small pixels, in the frame's own axes.
    const Eigen::Vector2d shift_px = scale * Eigen::Vector2d(at.x - range, at.y - range);
    const Eigen::Vector2d shift_camera_mm(shift_px.x() * camera.mm_per_px(), -shift_px.y() * camera.mm_per_px());
    const core::Pose2 candidate = prior * core::Pose2(shift_camera_mm, 0.0);
    TrackResult r = tracker_.Track(frame, candidate, candidate_covariance, reference_, scale_prior);
    if (!r.ok() || r.mean_zncc < options_.min_zncc) continue;
    KeepVerified(&verified, std::move(r));
  }
  if (verified.empty()) return none;
  if (gate) {
    // Only a place the prediction allows: one period of a repeating floor away is not.
    std::vector<TrackResult> allowed;
    double nearest_mm = std::numeric_limits<double>::infinity();
    double nearest_deg = 0.0;
    double nearest_nis = 0.0;
    for (TrackResult& r : verified) {
      const Eigen::Vector3d offset(r.world_from_camera.x_mm() - prior.x_mm(), r.world_from_camera.y_mm() - prior.y_mm(),
                                   core::WrapAngle(r.world_from_camera.yaw_rad() - prior.yaw_rad()));
      const Eigen::Matrix3d both = prior_covariance + gate->covariance_scale * r.covariance;
      const double nis = offset.dot(both.ldlt().solve(offset));
      if (offset.head<2>().norm() < nearest_mm) {
        nearest_mm = offset.head<2>().norm();
        nearest_deg = offset.z() * 180.0 / std::numbers::pi;
        nearest_nis = nis;
      }
      if (nis <= gate->chi2) allowed.push_back(std::move(r));
    }
    if (allowed.empty()) {
      const double sigma_mm = std::sqrt(std::max(prior_covariance(0, 0), prior_covariance(1, 1)));
      none.reason = "relocalization: " + std::to_string(verified.size()) +
                    " places match the frame, none within the prediction's uncertainty (the nearest " +
                    std::to_string(static_cast<int>(std::lround(nearest_mm))) + " mm off, sigma " +
                    std::to_string(static_cast<int>(std::lround(sigma_mm))) + " mm; " +
                    fmt::format("{:.2f} deg off, sigma {:.2f} deg; NIS {:.1f} against {:.1f})", nearest_deg,
                                std::sqrt(prior_covariance(2, 2)) * 180.0 / std::numbers::pi, nearest_nis, gate->chi2);
      return none;
    }
    if (gate->one_place && allowed.size() > 1) {
      TrackResult ambiguous;
      ambiguous.failure = TrackFailure::kAmbiguous;
      ambiguous.reason = "relocalization: " + std::to_string(allowed.size()) +
                         " places match the frame inside the prediction's uncertainty and the floor repeats (two of "
                         "them " +
                         std::to_string(static_cast<int>(
                             std::lround(Distance(allowed[0].world_from_camera, allowed[1].world_from_camera)))) +
                         " mm apart)";
      return ambiguous;
    }
    verified = std::move(allowed);
  }
  return ChooseRelocalization(std::move(verified), prior, options_.zncc_tie, options_.nearer_factor);
}

TrackResult Relocalizer::SearchEverywhere(const cv::Mat& frame, const PlaceIndex& places, double scale,
                                          PlaceLookup* lookup) const {
  const camera::IdealCamera camera = tracker_.camera().Scaled(scale);
  PlaceLookup found = places.Lookup(frame, camera);
  TrackResult none;
  none.failure = TrackFailure::kNoMatch;
  if (!found.problem.empty()) {
    none.reason = "global relocalization: " + found.problem;
  } else if (found.candidates.empty()) {
    none.reason = "global relocalization: no place on the map matches the frame (" +
                  std::to_string(found.frame_features) + " corners, " + std::to_string(found.matches) + " matches)";
  } else {
    none.reason = "global relocalization: none of " + std::to_string(found.candidates.size()) +
                  " candidate places verified";
  }
  // A candidate's pose is good to a corner's position at the index's level, and its yaw to
  // that over the corners' spread: a degree covers it.
  const double sigma_mm = 1.0;
  const double sigma_rad = 1.0 * std::numbers::pi / 180.0;
  const Eigen::Matrix3d around = Eigen::Vector3d(sigma_mm * sigma_mm, sigma_mm * sigma_mm, sigma_rad * sigma_rad).asDiagonal();
  std::vector<TrackResult> verified;
  int partial = 0;  // places that verified on some templates but not over the whole view
  for (const PlaceCandidate& candidate : found.candidates) {
    TrackResult r = tracker_.Track(frame, candidate.world_from_camera, around, reference_, scale);
    if (!r.ok() || r.mean_zncc < options_.min_zncc) continue;
    std::optional<TrackResult> whole = WholeView(frame, r, scale);
    if (!whole) {
      ++partial;
      continue;
    }
    KeepVerified(&verified, std::move(*whole));
    // The answer is settled: two places are ambiguous, and on a floor known to repeat so is one.
    if (verified.size() > 1 || places.floor_repeats() == true) break;
  }
  if (verified.empty() && partial > 0) {
    none.reason = "global relocalization: " + std::to_string(partial) + " of " +
                  std::to_string(found.candidates.size()) +
                  " candidate places matched part of the frame, none the whole of it";
  }
  const std::size_t candidates = found.candidates.size();
  if (lookup != nullptr) *lookup = std::move(found);
  if (verified.empty()) return none;
  // Without a prediction to choose by, a second place that verifies at all is a copy of the
  // floor (on a floor that does not repeat, a wrong place never verifies): even one that
  // matches less well may be the true place, seen partly off the map.
  if (verified.size() > 1) {
    std::sort(verified.begin(), verified.end(),
              [](const TrackResult& a, const TrackResult& b) { return a.mean_zncc > b.mean_zncc; });
    TrackResult ambiguous;
    ambiguous.failure = TrackFailure::kAmbiguous;
    ambiguous.reason = "global relocalization: two places match the frame (the floor repeats; " +
                       std::to_string(static_cast<int>(std::lround(
                           Distance(verified[0].world_from_camera, verified[1].world_from_camera)))) +
                       " mm apart, on " + InlierSummary(verified[0]) + " and " + InlierSummary(verified[1]) + ")";
    return ambiguous;
  }
  // On a floor whose self-test found copies, the index proposes a few of the places the frame's
  // corners vote for (max_candidates), not all of its copies: the one place that verified may
  // be a copy of the true place, which was not among them.
  if (places.floor_repeats() == true) {
    TrackResult ambiguous;
    ambiguous.failure = TrackFailure::kAmbiguous;
    ambiguous.reason = "global relocalization: a place of " + std::to_string(candidates) +
                       " candidates verified, but the floor repeats (the map's self-test) and the index "
                       "proposes only some of its copies";
    return ambiguous;
  }
  return std::move(verified.front());
}

TrackResult ChooseRelocalization(std::vector<TrackResult> verified, const core::Pose2& prior_camera, double zncc_tie,
                                 double nearer_factor) {
  if (verified.empty()) core::ThrowInvalidInput("ChooseRelocalization: no verified place");
  double best_zncc = 0.0;
  for (const TrackResult& r : verified) best_zncc = std::max(best_zncc, r.mean_zncc);
  std::vector<std::pair<double, std::size_t>> equal;  // (distance from the prediction, index)
  for (std::size_t i = 0; i < verified.size(); ++i) {
    if (verified[i].mean_zncc >= best_zncc - zncc_tie) {
      equal.emplace_back(Distance(verified[i].world_from_camera, prior_camera), i);
    }
  }
  std::sort(equal.begin(), equal.end());
  if (equal.size() == 1 || equal[1].first >= nearer_factor * equal[0].first) {
    return std::move(verified[equal[0].second]);
  }
  TrackResult ambiguous;
  ambiguous.failure = TrackFailure::kAmbiguous;
  const core::Pose2& a = verified[equal[0].second].world_from_camera;
  const core::Pose2& b = verified[equal[1].second].world_from_camera;
  ambiguous.reason = "relocalization: " + std::to_string(equal.size()) +
                     " places match the frame equally well (the floor repeats; two of them " +
                     std::to_string(static_cast<int>(std::lround(Distance(a, b)))) + " mm apart, " +
                     std::to_string(static_cast<int>(std::lround(equal[0].first))) + " and " +
                     std::to_string(static_cast<int>(std::lround(equal[1].first))) +
                     " mm from the prediction)";
  return ambiguous;
}

}  // namespace mosaicloc::tracking
