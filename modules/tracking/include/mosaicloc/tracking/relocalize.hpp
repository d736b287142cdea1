#pragma once

#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include "mosaicloc/core/pose2.hpp"
#include "mosaicloc/tracking/place_index.hpp"
#include "mosaicloc/tracking/reference.hpp"
#include "mosaicloc/tracking/tracker.hpp"

namespace mosaicloc::tracking {

/// The search for a frame over a stretch of the map (design.md section 7): the frame is
/// searched for at a coarse level of the map and the best peaks verified with the full tracker.
struct RelocalizeOptions {
  /// Map level of the search (3 = 8x coarser than the reference).
  int level = 3;
  /// Peaks of the coarse search verified at full resolution, best first.
  int candidates = 5;
  double min_zncc = 0.8;  ///< of the verifying registration
  /// A floor that repeats (tiles, a printed pattern) verifies in several places. Places whose
  /// ZNCC is within zncc_tie of the best are equally good; of those the one nearest the
  /// prediction is taken only if the next is at least nearer_factor times as far, else the
  /// frame is ambiguous and no place is taken.
  double zncc_tie = 0.02;
  double nearer_factor = 2.0;
  /// Share of a candidate place the map must cover. Less than 1: a vehicle that mapped one
  /// lane and drives it a few mm aside sees a sliver of floor the map does not have.
  float min_coverage = 0.75F;
  /// A place found without a prior (SearchEverywhere) is verified once more on this many
  /// templates spread over the whole frame, and kept only if at least `min_inlier_share` of
  /// those searched on the map agree: the view must match as a whole, not in a corner whose
  /// floor also lies elsewhere (0: not verified again).
  int whole_view_templates = 12;
  double min_inlier_share = 0.5;
  bool Check(std::string* why) const;
};

/// The prediction's gate: a verified place is kept only if its squared Mahalanobis distance to
/// the prediction (the prediction's covariance plus covariance_scale times the place's) is at
/// most chi2, as for a fix.
struct RelocalizeGate {
  double chi2 = 0.0;
  double covariance_scale = 1.0;
  /// On a floor known to repeat: two places inside the gate are two copies the prediction
  /// cannot tell apart, however much nearer one is (a prediction wrong by more than its
  /// covariance says puts a copy nearest), so the frame is kAmbiguous.
  bool one_place = false;
};

/// Relocalization: finds where on the map a frame was taken, within a radius of a predicted
/// camera pose, or anywhere on it through its place index. Const, like the tracker it verifies with.
class Relocalizer {
 public:
  /// `tracker` and `reference` (the map, level 0) must outlive the relocalizer. Throws
  /// core::Error (invalid input) when options fail Check().
  Relocalizer(const Tracker& tracker, const ReferenceRaster& reference, const RelocalizeOptions& options);

  /// Searches `radius_mm` around `prior` (world_from_camera; `prior_covariance` gives the
  /// verification's yaw uncertainty and the gate's distances) on the coarse map, verifies the
  /// best candidates, and takes one of the verified places: with a `gate` only places inside
  /// it, then ChooseRelocalization. Never throws for a frame that cannot be placed: the result
  /// says why (kNoMatch: no place verified, or none inside the gate; kAmbiguous: equally good
  /// places that the prediction does not decide between). `scale` is the image scale the
  /// frame is expected at (TrackResult::scale).
  TrackResult Search(const cv::Mat& frame, const core::Pose2& prior, const Eigen::Matrix3d& prior_covariance,
                     double radius_mm, const std::optional<RelocalizeGate>& gate, double scale = 1.0) const;

  /// Searches the whole map, without a prior (design.md section 7b): the place index's
  /// candidates are verified with the tracker, and a verified place is taken only if it is the
  /// only one: with no prediction to choose by, two verified places (a floor that repeats; the
  /// true place seen partly off the map and a copy whole) make the frame kAmbiguous, and so does
  /// a single verified place on a floor the map's self-test found to repeat (the index proposes
  /// only some of a frame's copies, so the true place may not have been tried). kNoMatch when no
  /// candidate verifies or the index cannot be used (the reason says which). `lookup`, when
  /// given, gets what the index found.
  TrackResult SearchEverywhere(const cv::Mat& frame, const PlaceIndex& places, double scale = 1.0,
                               PlaceLookup* lookup = nullptr) const;

 private:
  /// Verifies a place the tracker registered once more over the whole frame
  /// (RelocalizeOptions::whole_view_templates); nullopt when the view does not match as a whole.
  std::optional<TrackResult> WholeView(const cv::Mat& frame, const TrackResult& place, double scale) const;

  const Tracker& tracker_;
  const ReferenceRaster& reference_;
  RelocalizeOptions options_;
  std::optional<Tracker> whole_view_;  ///< the tracker with whole_view_templates
};

/// Of the places a relocalization verified (distinct, each a successful registration), the
/// one to take: among those whose mean ZNCC is within `zncc_tie` of the best, the nearest to
/// the predicted camera pose, if the next nearest is at least `nearer_factor` times as far;
/// otherwise a kAmbiguous result saying how many places matched. Throws core::Error (invalid
/// input) when `verified` is empty.
TrackResult ChooseRelocalization(std::vector<TrackResult> verified, const core::Pose2& prior_camera, double zncc_tie,
                                 double nearer_factor);

}  // namespace mosaicloc::tracking
