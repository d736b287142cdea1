#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <fstream>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "mosaicloc/core/pose2.hpp"
#include "mosaicloc/core/timestamp.hpp"
#include "mosaicloc/core/wheel_geometry.hpp"
#include "mosaicloc/dataset/trajectory.hpp"

namespace mosaicloc::dataset {

/// Dataset layout (design.md section 4):
///   DIR/dataset.yaml, DIR/cam0/data.csv, DIR/cam0/data/<ns>.png,
///   DIR/encoders/data.csv, DIR/groundtruth/data.tum (optional).
inline constexpr int kFormatVersion = 1;

struct CameraInfo {
  int width_px = 640;
  int height_px = 480;
  double mm_per_px = 0.25;             ///< ideal (rectified) image scale
  core::Pose2 vehicle_from_camera;     ///< calibrated mounting, mm and rad
};

/// Wheel geometry as the vehicle is calibrated (what odometry should use).
using VehicleInfo = core::WheelGeometry;

struct DatasetInfo {
  CameraInfo camera;
  VehicleInfo vehicle;
  /// Free-form key/value record of where the data came from (simulator settings, site, ...).
  std::map<std::string, std::string> provenance;
};

struct Frame {
  core::Timestamp time;
  std::filesystem::path path;
  cv::Mat image;  ///< CV_8UC1, camera width x height
};

/// One reading of the vehicle's encoder counters (raw PLC values, which may wrap); which are
/// the vehicle's kind's (core::DriveKind): a differential drive's left and right wheel, a
/// tricycle's drive wheel and steering angle, a mecanum vehicle's four wheels (left and right
/// the front ones). The others stay 0.
struct EncoderSample {
  core::Timestamp time;
  core::EncoderCounts counts;  ///< the vehicle kind's counters; the others 0
};

/// Reads a dataset as a stream: frames and encoder samples one at a time, each line and
/// file validated as it is read. Every problem is a core::Error (invalid input) whose message
/// starts with "file:line: ".
///
/// One fault of a recording is not an error: a row whose time is not after the row before it
/// (a frame or sample recorded twice, or out of order, or behind a clock that stepped back).
/// Such rows are skipped, so that every reader sees times that increase; the reader warns once
/// per file, naming the lines, and counts them (skipped_frames(), skipped_encoder_samples()).
class DatasetReader {
 public:
  /// Opens DIR and validates dataset.yaml and the presence and headers of the CSV files.
  explicit DatasetReader(const std::filesystem::path& directory);

  const std::filesystem::path& directory() const { return directory_; }
  const DatasetInfo& info() const { return info_; }
  /// Rows of cam0/data.csv the frame stream gives (their files are checked as they are read).
  std::int64_t frame_rows() const { return frame_rows_; }
  /// Rows of cam0/data.csv and of the encoder file skipped for their time.
  std::int64_t skipped_frames() const { return skipped_frames_; }
  std::int64_t skipped_encoder_samples() const { return skipped_encoder_samples_; }

  class FrameStream {
   public:
    /// The next frame with its decoded image, or nothing at the end.
    /// With decode = false only the file's existence is checked (image left empty).
    std::optional<Frame> Next(bool decode = true);
    /// The next frame, its image decoded only when `decode_if(its time)` says so.
    std::optional<Frame> Next(const std::function<bool(core::Timestamp)>& decode_if);

   private:
    friend class DatasetReader;
    FrameStream(std::filesystem::path directory, const CameraInfo& camera);
    std::filesystem::path directory_;
    std::filesystem::path csv_;
    CameraInfo camera_;
    std::ifstream in_;
    int line_number_ = 1;
    std::optional<core::Timestamp> last_time_;
  };

  class EncoderStream {
   public:
    std::optional<EncoderSample> Next();

   private:
    friend class DatasetReader;
    EncoderStream(std::filesystem::path csv, core::DriveKind kind);
    std::filesystem::path csv_;
    core::DriveKind kind_;
    std::ifstream in_;
    int line_number_ = 1;
    std::optional<core::Timestamp> last_time_;
  };

  FrameStream Frames() const;
  EncoderStream Encoders() const;
  bool HasGroundTruth() const;
  /// The ground truth trajectory (world_from_vehicle); throws if absent or invalid.
  Trajectory GroundTruth() const;

  /// Reads everything once (decoding every image) and throws on the first problem.
  struct Summary {
    std::int64_t frames = 0;
    std::int64_t encoder_samples = 0;
    std::int64_t groundtruth_poses = 0;
    double duration_s = 0.0;
    std::int64_t skipped_frames = 0;           ///< rows skipped for their time (see above)
    std::int64_t skipped_encoder_samples = 0;
    /// "valid: F frames, E encoder samples, G ground-truth poses, D s", and a second line
    /// with the skipped rows when there are any.
    std::string Describe() const;
  };
  Summary Validate() const;

 private:
  std::filesystem::path directory_;
  DatasetInfo info_;
  std::int64_t frame_rows_ = 0;
  std::int64_t skipped_frames_ = 0;
  std::int64_t skipped_encoder_samples_ = 0;
};

/// Writes a dataset so that it appears complete or not at all: everything goes to a hidden
/// staging directory beside the target, and Commit() renames it into place. Destroying the
/// writer without Commit() removes the staging directory and leaves the target untouched.
class DatasetWriter {
 public:
  /// Throws core::Error if the target exists and overwrite is false, or on I/O failure.
  DatasetWriter(const std::filesystem::path& directory, const DatasetInfo& info, bool overwrite);
  ~DatasetWriter();
  DatasetWriter(const DatasetWriter&) = delete;
  DatasetWriter& operator=(const DatasetWriter&) = delete;

  /// Adds a frame (CV_8UC1 of the camera size); times must strictly increase.
  void AddFrame(core::Timestamp time, const cv::Mat& image);
  /// Encodes a frame as the dataset stores it (lossless PNG). Thread-safe, so producers can
  /// encode in parallel and hand the bytes to AddEncodedFrame in order.
  static std::vector<unsigned char> EncodeFrame(const cv::Mat& image);
  /// Adds a frame encoded by EncodeFrame from an image of the camera size.
  void AddEncodedFrame(core::Timestamp time, const std::vector<unsigned char>& png);
  void AddEncoderSample(const EncoderSample& sample);
  void SetGroundTruth(const Trajectory& world_from_vehicle);
  /// Adds a file of the caller's (e.g. a live run's fixes) at `relative` inside the dataset;
  /// it appears with the rest at Commit(). Paths that leave the dataset are refused.
  void AddFile(const std::filesystem::path& relative, std::string_view content);
  /// Flushes, closes and renames the staging directory into place.
  void Commit();

 private:
  std::filesystem::path directory_;
  std::filesystem::path staging_;
  DatasetInfo info_;
  bool overwrite_ = false;
  bool committed_ = false;
  std::ofstream frames_csv_;
  std::ofstream encoders_csv_;
  std::optional<core::Timestamp> last_frame_time_;
  std::optional<core::Timestamp> last_encoder_time_;
  std::optional<Trajectory> groundtruth_;
};

/// The header of a recording derived from `reader`'s (the same drive through another camera,
/// or rectified): its info with `camera` in place and `note` as provenance "calibration".
DatasetInfo DerivedInfo(const DatasetReader& reader, const CameraInfo& camera, const std::string& note);
/// The vehicle a simulated drive was really driven with, as the simulator records it in the
/// provenance (truth_vehicle_from_camera "x_mm y_mm yaw_rad", then the kind's
/// truth_left_wheel_radius_mm, truth_right_wheel_radius_mm, truth_track_width_mm or
/// truth_drive_wheel_radius_mm, truth_wheelbase_mm, truth_steering_offset_deg): what a
/// calibration is checked against. Localization never reads it.
struct VehicleTruth {
  core::Pose2 vehicle_from_camera;
  core::WheelGeometry wheels;  ///< ticks_per_revolution is the dataset's
};
void RecordVehicleTruth(const VehicleTruth& truth, DatasetInfo* info);
/// The recorded truth, or nothing when the provenance holds none. Throws core::Error (invalid
/// input) naming the key when a value is not a number.
std::optional<VehicleTruth> RecordedVehicleTruth(const DatasetInfo& info);
/// Writes an image as a lossless PNG, atomically. Throws core::Error naming the file.
void WritePng(const std::filesystem::path& file, const cv::Mat& image);
/// Copies `reader`'s encoder samples and ground truth (when it has one) into `writer`.
void CopyEncodersAndTruth(const DatasetReader& reader, DatasetWriter* writer);

/// Reads and validates DIR/dataset.yaml alone.
DatasetInfo ReadDatasetInfo(const std::filesystem::path& yaml_file);

}  // namespace mosaicloc::dataset
