#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "mosaicloc/dataset/evaluation.hpp"
#include "mosaicloc/dataset/fixes.hpp"
#include "mosaicloc/dataset/trajectory.hpp"

namespace mosaicloc::dataset {

/// The chi-square distribution's 95 % quantile for 3 degrees of freedom: the bound a fix's
/// normalized innovation squared stays under 95 % of the time when the filter's covariances
/// are true.
inline constexpr double kNis95Bound3Dof = 7.8147;

/// The lock state's name for a fixes.csv status (design.md section 6): "none" (0, the
/// baseline modes), "tracking", "degraded", "lost", "off-map", "searching".
const char* StatusName(int status);

/// What a replay says about itself without ground truth (design.md section 4), into
/// `metrics`: the estimate's path length and speeds (estimate_*), frames and fixes per lock
/// state, frames without a fix per reason, and the filter's consistency from the reports'
/// NIS (nis_*). `normalized_innovations` (x, y, yaw innovation over its predicted standard
/// deviation, one per judged fix; may be empty) gives innovation_sigma_ratio.
void AddTruthFreeFigures(const std::vector<FrameReport>& reports, const Trajectory& estimate,
                         const std::vector<Eigen::Vector3d>& normalized_innovations, Metrics* metrics);

}  // namespace mosaicloc::dataset
