#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "mosaicloc/core/pose2.hpp"
#include "mosaicloc/runtime/settings.hpp"

namespace mosaicloc::runtime {

/// `mosaicloc locate`: where on a map single frames were taken, without any prior (global
/// relocalization, design.md section 7b). The frames are ideal images at the map's resolution:
/// PNG files, or every `every`-th frame of a dataset, whose ground truth (when it has one) each
/// answer is compared with.
struct LocateOptions {
  std::filesystem::path map;
  std::vector<std::filesystem::path> images;
  std::filesystem::path dataset;  ///< instead of images
  int every = 1;                  ///< with a dataset: every k-th frame
  std::int64_t max_frames = 0;    ///< with a dataset: at most this many (0: all)
  LocalizationSettings settings;  ///< the tracker that verifies the candidates, and relocalize.*
  double scale = 1.0;             ///< image scale the frames were taken at (1: the calibrated height)
  double wrong_mm = 1.0;          ///< with ground truth: an answer this far off is wrong
};

struct LocatedFrame {
  std::string frame;    ///< the image's path, or the dataset frame's
  std::string outcome;  ///< "found", "ambiguous" or "no-match"
  std::string reason;   ///< why not, when not found
  core::Pose2 world_from_camera;  ///< when found
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  double mean_zncc = 0.0;
  int inliers = 0;              ///< templates of the verifying registration
  int candidates = 0;           ///< places the index proposed
  double milliseconds = 0.0;    ///< frame in, verified answer out
  std::optional<double> error_mm;  ///< against the ground truth's camera pose, when there is one

  double SigmaMm() const;  ///< the found position's larger standard deviation
  /// frame, outcome, candidates, milliseconds; the pose, sigma_mm, zncc and templates when
  /// found, else the reason; error_mm with a ground truth.
  nlohmann::json ToJson() const;
};

struct LocateSummary {
  std::vector<LocatedFrame> frames;
  int found = 0, ambiguous = 0, no_match = 0;
  /// Answers compared with a ground truth, those within 0.05 mm of it and those over wrong_mm.
  int checked = 0, within_0_05_mm = 0, wrong = 0;
  double ms_p50 = 0.0, ms_p99 = 0.0, ms_max = 0.0;  ///< frame in, verified answer out
  std::int64_t index_features = 0;
  std::int64_t index_memory_bytes = 0;
  double index_load_s = 0.0;

  /// What `locate --json` prints: the counts, times, index figures, every frame
  /// (LocatedFrame::ToJson), and with a ground truth checked, within_0_05_mm and wrong.
  nlohmann::json ToJson(const std::filesystem::path& map) const;
};

/// Throws core::Error (invalid input) for an unreadable map or image, or a map without a place
/// index (naming `mosaicloc map index`).
LocateSummary Locate(const LocateOptions& options, const std::function<void(double)>& progress = {});

}  // namespace mosaicloc::runtime
