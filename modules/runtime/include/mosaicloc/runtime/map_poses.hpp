#pragma once

#include <filesystem>
#include <functional>
#include <optional>
#include <vector>

#include <nlohmann/json.hpp>

#include "mosaicloc/core/pose2.hpp"
#include "mosaicloc/dataset/dataset.hpp"
#include "mosaicloc/dataset/trajectory.hpp"
#include "mosaicloc/mapping/mapper.hpp"

namespace mosaicloc::runtime {

/// The mapper's defaults for a mapping drive: the localizer's matcher with sixteen templates
/// (a pair of frames overlaps less than a frame and the map, and the yaw of every pair adds to
/// the chain's drift: more templates over the view measure it better).
mapping::MapperOptions DefaultMapperOptions();

/// `mosaicloc map poses` (and the first step of `map build`): a mapping drive's poses from its
/// frames and encoders alone.
struct MapPosesOptions {
  std::filesystem::path dataset;
  std::filesystem::path out;        ///< the optimized trajectory (TUM), or empty
  std::filesystem::path report;     ///< the consistency report's directory, or empty
  std::filesystem::path graph_out;  ///< the pose graph in g2o's format, or empty
  /// Each frame's estimated view (height and tilt, section 7a) in groundtruth/camera.csv's
  /// format (no centre offsets: the poses are where the camera looked), when the view
  /// geometry was applied, so that a map is painted with it; drive k's at DrivePath(views_out,
  /// k). Where it was not applied the files are removed. Empty: not written.
  std::filesystem::path views_out;
  /// A pose graph (g2o) of this drive's frames, one node per frame with encoder data in order
  /// (world_from_camera), to optimize instead of registering the frames: e.g. one exported and
  /// edited, or built by another tool.
  std::filesystem::path graph_in;
  /// The vehicle's pose at the first frame, which places the map; else the dataset's
  /// (StartPose: its ground truth's or a recording's noted start, else the origin).
  std::optional<core::Pose2> start;
  /// Later drives over the same site, mapped with the first into one map: each starts where
  /// its dataset says (StartPose), known to within join_start_sigma_mm / _deg; loop closures
  /// onto the floor the drives before it mapped join it to them. Drive k's (2, 3, ...) poses
  /// go to DrivePath(out, k).
  std::vector<std::filesystem::path> joined;
  double join_start_sigma_mm = 20.0;
  double join_start_sigma_deg = 1.0;
  mapping::MapperOptions mapper = DefaultMapperOptions();
  /// The camera's flat field (its vignetting, a light fixed to the vehicle) estimated from the
  /// drives and divided out of every frame before it is registered (MappingFlatField). Off
  /// only for a camera whose frames are already flat, or to compare.
  bool flat_field = true;
};

/// The flat field the frames are registered through: the brightness pattern that stays on the
/// pixels while the floor moves, estimated from `flat_frames` frames spread along the drives.
/// A pattern left in the frames biases every registration of one frame against another by a
/// fixed fraction of their motion (calibration::FlatFieldEstimator), which the chain of frames
/// adds up: on the brick floor with the simulator's 15 % vignetting, links 2e-5 too long and
/// bent by -0.1 urad per mm driven.
struct MappingFlatField {
  cv::Mat gain;         ///< relative, mean 1 (CV_32F, the frames' size); empty: not estimated
  int flat_frames = 0;  ///< frames it was estimated from
  double min_gain = 1.0, max_gain = 1.0;
};
/// From frames at least `spacing_mm` of wheel travel apart (so that each shows other floor),
/// every drive's from its start, at most `max_frames` (the spacing grows to keep to it over a
/// long drive). Empty when fewer than `min_frames` are that far apart: the vehicle hardly
/// moved, and a median of a few views would keep the floor's own pattern.
/// `first_of_drive[k]` is the index at which drive k starts in `wheels`.
MappingFlatField EstimateMappingFlatField(const std::function<cv::Mat(std::size_t)>& load_frame,
                                          const std::vector<core::Pose2>& wheels,
                                          const std::vector<std::size_t>& first_of_drive, double spacing_mm,
                                          int max_frames = 400, int min_frames = 24);

/// Where drive k's trajectory goes when drive 1's goes to `out`: out itself for k = 1, else
/// out with ".k" before its extension (poses.tum, poses.2.tum, ...).
std::filesystem::path DrivePath(const std::filesystem::path& out, int k);

/// How well a trajectory fits the ground truth after the best rigid alignment of its frame.
struct AlignedError {
  double rms_mm = 0.0;
  double max_mm = 0.0;
  double heading_rms_deg = 0.0;
  /// That alignment: the trajectory's frame (a built map's) in the truth's.
  core::Pose2 truth_from_estimate;
};

struct MapPosesSummary {
  mapping::MappingResult mapping;
  /// world_from_vehicle at each frame that has a pose, per drive (the first, then the joined)
  std::vector<dataset::Trajectory> poses;
  /// Of the optimized poses, and the chained ones (before loop closure), against the ground
  /// truth of every drive that has one.
  std::optional<AlignedError> error;
  std::optional<AlignedError> chained_error;
  double seconds = 0.0;
  std::int64_t encoder_samples_rejected = 0;
  MappingFlatField flat_field;  ///< what the frames were registered through

  /// What `map poses --json` prints (and `map build --json` under "mapping"): the counts, the
  /// seams after optimization, the flat field (frames, least and greatest gain), the errors
  /// against the ground truth (null without one), warnings.
  nlohmann::json ToJson() const;
};

/// Estimates the drive's poses (mapping::MapPoses), writes what the options ask for, and
/// compares with the ground truth where the dataset has one. Throws core::Error (invalid
/// input) for a dataset that cannot be read.
MapPosesSummary EstimateMapPoses(const MapPosesOptions& options, const std::function<void(double)>& progress = {});
/// The same with the drives already open (options.dataset's, then each joined one's), so that
/// a caller that reads them again (map build) opens and checks each once.
MapPosesSummary EstimateMapPoses(const MapPosesOptions& options, const std::vector<const dataset::DatasetReader*>& readers,
                                 const std::function<void(double)>& progress = {});

/// The consistency report: consistency.json (the figures), loops.csv (every loop tried, why
/// the rejected ones were), seams.csv (every registered pair's residual before and after
/// optimization) and residuals.png (where on the map the residuals are large).
void WriteMappingReport(const std::filesystem::path& directory, const MapPosesSummary& summary);

}  // namespace mosaicloc::runtime
