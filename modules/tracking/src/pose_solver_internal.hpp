#pragma once

#include <cstddef>
#include <vector>

#include "mosaicloc/core/pose2.hpp"
#include "mosaicloc/tracking/pose_solver.hpp"

// What the robust solver and the Kalman observer share.
namespace mosaicloc::tracking::internal {

/// How many distinct template positions (camera_mm) the used correspondences have, counted up
/// to `enough`.
int DistinctPoints(const std::vector<Correspondence>& correspondences, const std::vector<bool>& use,
                   std::size_t enough);

/// A solution at `initial` with no inlier and zero residuals, one per correspondence; failed
/// (kTooFewInliers) when there are fewer correspondences than `min_inliers` (or none).
PoseSolution StartSolution(const std::vector<Correspondence>& correspondences, const core::Pose2& initial,
                           int min_inliers);

}  // namespace mosaicloc::tracking::internal
