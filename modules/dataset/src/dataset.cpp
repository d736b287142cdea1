#include "mosaicloc/dataset/dataset.hpp"

#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <iomanip>
#include <limits>
#include <sstream>
#include <vector>

#include <opencv2/imgcodecs.hpp>
#include <yaml-cpp/yaml.h>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/core/file.hpp"
#include "mosaicloc/core/log.hpp"
#include "mosaicloc/core/yaml.hpp"
#include "mosaicloc/dataset/frame_png.hpp"
#include "text_fields.hpp"

namespace mosaicloc::dataset {
namespace fs = std::filesystem;
namespace {

constexpr const char* kFramesCsv = "cam0/data.csv";
constexpr const char* kFramesDir = "cam0/data";
constexpr const char* kEncodersCsv = "encoders/data.csv";
constexpr const char* kGroundTruth = "groundtruth/data.tum";
constexpr const char* kFramesHeader = "#timestamp_ns,filename";
// The encoder file's columns after the time: the vehicle kind's counters.
struct EncoderColumns {
  const char* header;
  int count;
  const char* names[4];
  std::int32_t core::EncoderCounts::*fields[4];
};
EncoderColumns ColumnsOf(core::DriveKind kind) {
  using S = core::EncoderCounts;
  switch (kind) {
    case core::DriveKind::kTricycle:
      return {"#timestamp_ns,drive_ticks,steering_ticks", 2, {"drive_ticks", "steering_ticks"},
              {&S::drive_ticks, &S::steering_ticks}};
    case core::DriveKind::kMecanum:
      return {"#timestamp_ns,front_left_ticks,front_right_ticks,rear_left_ticks,rear_right_ticks", 4,
              {"front_left_ticks", "front_right_ticks", "rear_left_ticks", "rear_right_ticks"},
              {&S::left_ticks, &S::right_ticks, &S::rear_left_ticks, &S::rear_right_ticks}};
    case core::DriveKind::kDifferential: break;
  }
  return {"#timestamp_ns,left_ticks,right_ticks", 2, {"left_ticks", "right_ticks"}, {&S::left_ticks, &S::right_ticks}};
}

using detail::LineError;
using detail::ParseInt64;
using detail::SplitCsv;
using detail::Trim;

// Reads the next non-empty line; returns false at the end of the file.
bool NextLine(std::ifstream& in, int* line_number, std::string* line) {
  while (std::getline(in, *line)) {
    ++*line_number;
    if (!Trim(*line).empty()) return true;
  }
  return false;
}

// Opens a CSV and reads its header line (into `first`, when given), which must be a comment.
void OpenCsv(const fs::path& csv, const char* header, std::ifstream* in, std::string* first = nullptr) {
  in->open(csv);
  if (!*in) core::ThrowInvalidInput(csv.string() + ": missing or unreadable");
  std::string line;
  if (!std::getline(*in, line)) LineError(csv, 1, "empty file: expected the header '" + std::string(header) + "'");
  if (Trim(line).rfind('#', 0) != 0) {
    LineError(csv, 1, "expected the header '" + std::string(header) + "', got '" + Trim(line) + "'");
  }
  if (first) *first = line;
}

// An encoder file whose header names another kind's counters is not this vehicle's.
void CheckEncoderHeader(const fs::path& csv, const std::string& header, core::DriveKind kind) {
  std::vector<std::string> named = SplitCsv(header.substr(header.rfind('#', 0) == 0 ? 1 : 0));
  for (std::string& name : named) name = Trim(name);
  const auto names_a_column = [&named](const EncoderColumns& columns) {
    for (int i = 0; i < columns.count; ++i) {
      if (std::find(named.begin(), named.end(), columns.names[i]) != named.end()) return true;
    }
    return false;
  };
  for (const core::DriveKind other : core::kDriveKinds) {
    if (other != kind && names_a_column(ColumnsOf(other)) && !names_a_column(ColumnsOf(kind))) {
      LineError(csv, 1,
                "the header names a " + std::string(core::ToString(other)) + "'s counters, but dataset.yaml's "
                "vehicle.kind is " + core::ToString(kind) + " (expected '" + ColumnsOf(kind).header + "')");
    }
  }
}

core::Timestamp ParseTime(const fs::path& file, int line, const std::string& text) {
  std::int64_t ns = 0;
  if (!ParseInt64(text, &ns)) LineError(file, line, "timestamp_ns '" + text + "' is not an integer");
  return core::Timestamp::FromNanoseconds(ns);
}

// Whether a row at `time` comes after the last one kept (the streams skip it otherwise).
bool InOrder(core::Timestamp time, std::optional<core::Timestamp>* last) {
  if (*last && time <= **last) return false;
  *last = time;
  return true;
}

// Counts the rows of a CSV whose time is not after the row kept before them (`kept`: the
// others), warning once with the first few lines. Only the time field is read: the streams
// check the rest. `first`: the header line, when given.
std::int64_t SkippedRows(const fs::path& csv, const char* header, std::int64_t* kept = nullptr,
                         std::string* first = nullptr) {
  std::ifstream in;
  OpenCsv(csv, header, &in, first);
  int line_number = 1;
  std::string line;
  std::optional<core::Timestamp> last;
  std::int64_t skipped = 0;
  std::string lines;
  while (NextLine(in, &line_number, &line)) {
    const std::string field = line.substr(0, line.find(','));
    const core::Timestamp time = ParseTime(csv, line_number, Trim(field));
    const std::optional<core::Timestamp> before = last;
    if (InOrder(time, &last)) {
      if (kept) ++*kept;
      continue;
    }
    if (++skipped <= 5) {
      lines += (skipped > 1 ? ", " : "") + std::to_string(line_number) + " (" + std::to_string(time.nanoseconds()) +
               " after " + std::to_string(before->nanoseconds()) + ")";
    }
  }
  if (skipped > 0) {
    core::Log().warn("{}: {} row{} skipped: not after the row before in time (recorded twice, out of order, or "
                     "behind a clock that stepped back): line{} {}{}",
                     csv.string(), skipped, skipped > 1 ? "s" : "", skipped > 1 ? "s" : "", lines,
                     skipped > 5 ? " and more" : "");
  }
  return skipped;
}

std::string FrameFileName(core::Timestamp time) { return std::to_string(time.nanoseconds()) + ".png"; }

}  // namespace

DatasetInfo ReadDatasetInfo(const fs::path& yaml_file) {
  const YAML::Node node = core::LoadYamlFile(yaml_file);
  core::YamlProblems problems;
  core::YamlMap root = core::YamlMap::Root(node, yaml_file.string(), &problems);
  DatasetInfo info;
  int format_version = 0;
  root.Required("format_version", &format_version,
                core::IntegerInRange(kFormatVersion, kFormatVersion));

  core::YamlMap camera = root.RequiredMap("camera");
  camera.Required("width_px", &info.camera.width_px, core::IntegerInRange(8, 16384));
  camera.Required("height_px", &info.camera.height_px, core::IntegerInRange(8, 16384));
  camera.Required("mm_per_px", &info.camera.mm_per_px, core::InRange(1e-4, 100.0));
  core::YamlMap mount = camera.RequiredMap("vehicle_from_camera");
  double x_mm = 0.0;
  double y_mm = 0.0;
  double yaw_rad = 0.0;
  mount.Required("x_mm", &x_mm);
  mount.Required("y_mm", &y_mm);
  mount.Required("yaw_rad", &yaw_rad, core::InRange(-4.0, 4.0));
  mount.Finish();
  info.camera.vehicle_from_camera = core::Pose2(x_mm, y_mm, yaw_rad);
  camera.Finish();

  core::YamlMap vehicle = root.RequiredMap("vehicle");
  core::ReadWheelGeometry(vehicle, &info.vehicle, /*required=*/true);
  vehicle.Finish();

  if (root.Has("provenance")) {
    const YAML::Node provenance = node["provenance"];
    root.OptionalMap("provenance");  // marks the key as known
    if (provenance.IsMap()) {
      for (const auto& entry : provenance) {
        if (!entry.first.IsScalar()) {
          problems.Add(yaml_file.string() + ":" + std::to_string(entry.first.Mark().line + 1) +
                       ": provenance: a key must be a plain name, not a mapping or a list");
          continue;
        }
        if (!entry.second.IsScalar()) {
          problems.Add(yaml_file.string() + ":" + std::to_string(entry.second.Mark().line + 1) +
                       ": provenance." + entry.first.Scalar() + ": expected a text value");
          continue;
        }
        info.provenance[entry.first.Scalar()] = entry.second.Scalar();
      }
    }
  }
  root.Finish();
  problems.ThrowIfAny();
  return info;
}

DatasetReader::DatasetReader(const fs::path& directory) : directory_(directory) {
  std::error_code ec;
  if (!fs::is_directory(directory_, ec)) core::ThrowInvalidInput(directory_.string() + ": no such dataset directory");
  info_ = ReadDatasetInfo(directory_ / "dataset.yaml");
  // Fail early on a missing or headless CSV, or a bad time, rather than after minutes of processing.
  skipped_frames_ = SkippedRows(directory_ / kFramesCsv, kFramesHeader, &frame_rows_);
  std::string encoder_header;
  skipped_encoder_samples_ =
      SkippedRows(directory_ / kEncodersCsv, ColumnsOf(info_.vehicle.kind).header, nullptr, &encoder_header);
  CheckEncoderHeader(directory_ / kEncodersCsv, encoder_header, info_.vehicle.kind);
}

DatasetReader::FrameStream::FrameStream(fs::path directory, const CameraInfo& camera)
    : directory_(std::move(directory)), csv_(directory_ / kFramesCsv), camera_(camera) {
  OpenCsv(csv_, kFramesHeader, &in_);
}

std::optional<Frame> DatasetReader::FrameStream::Next(bool decode) {
  return Next([decode](core::Timestamp) { return decode; });
}

std::optional<Frame> DatasetReader::FrameStream::Next(const std::function<bool(core::Timestamp)>& decode_if) {
  std::string line;
  std::vector<std::string> fields;
  Frame frame;
  do {
    if (!NextLine(in_, &line_number_, &line)) return std::nullopt;
    fields = SplitCsv(line);
    if (fields.size() != 2) {
      LineError(csv_, line_number_, "expected 2 fields 'timestamp_ns,filename', got " + std::to_string(fields.size()));
    }
    frame.time = ParseTime(csv_, line_number_, fields[0]);
  } while (!InOrder(frame.time, &last_time_));
  const std::string& name = fields[1];
  if (name.empty() || name.find('/') != std::string::npos || name == "." || name == "..") {
    LineError(csv_, line_number_, "filename '" + name + "' must be a plain file name inside " + kFramesDir);
  }
  frame.path = directory_ / kFramesDir / name;
  std::error_code ec;
  if (!fs::is_regular_file(frame.path, ec)) LineError(csv_, line_number_, "image " + frame.path.string() + " is missing");
  if (decode_if(frame.time)) {
    frame.image = ReadImageFile(frame.path);
    if (frame.image.empty()) LineError(csv_, line_number_, "image " + frame.path.string() + " cannot be decoded");
    if (frame.image.type() != CV_8UC1) {
      LineError(csv_, line_number_, "image " + frame.path.string() + " is not 8-bit grey (" +
                                        std::to_string(frame.image.channels()) + " channels, depth " +
                                        std::to_string(frame.image.depth()) + ")");
    }
    if (frame.image.cols != camera_.width_px || frame.image.rows != camera_.height_px) {
      LineError(csv_, line_number_, "image " + frame.path.string() + " is " + std::to_string(frame.image.cols) + "x" +
                                        std::to_string(frame.image.rows) + ", dataset.yaml says " +
                                        std::to_string(camera_.width_px) + "x" + std::to_string(camera_.height_px));
    }
  }
  return frame;
}

DatasetReader::EncoderStream::EncoderStream(fs::path csv, core::DriveKind kind) : csv_(std::move(csv)), kind_(kind) {
  OpenCsv(csv_, ColumnsOf(kind_).header, &in_);
}

std::optional<EncoderSample> DatasetReader::EncoderStream::Next() {
  std::string line;
  std::vector<std::string> fields;
  EncoderSample sample;
  const EncoderColumns columns = ColumnsOf(kind_);
  do {
    if (!NextLine(in_, &line_number_, &line)) return std::nullopt;
    fields = SplitCsv(line);
    const std::size_t expected = static_cast<std::size_t>(columns.count) + 1;
    if (fields.size() != expected) {
      LineError(csv_, line_number_,
                "expected " + std::to_string(expected) + " fields '" + std::string(columns.header + 1) + "', got " +
                    std::to_string(fields.size()));
    }
    sample.time = ParseTime(csv_, line_number_, fields[0]);
  } while (!InOrder(sample.time, &last_time_));
  for (int i = 0; i < columns.count; ++i) {
    std::int64_t value = 0;
    if (!ParseInt64(fields[static_cast<std::size_t>(i) + 1], &value) ||
        value < std::numeric_limits<std::int32_t>::min() || value > std::numeric_limits<std::int32_t>::max()) {
      LineError(csv_, line_number_, std::string(columns.names[i]) + " '" + fields[static_cast<std::size_t>(i) + 1] +
                                        "' is not an int32 counter value");
    }
    sample.counts.*columns.fields[i] = static_cast<std::int32_t>(value);
  }
  return sample;
}

DatasetReader::FrameStream DatasetReader::Frames() const { return FrameStream(directory_, info_.camera); }

DatasetReader::EncoderStream DatasetReader::Encoders() const {
  return EncoderStream(directory_ / kEncodersCsv, info_.vehicle.kind);
}

bool DatasetReader::HasGroundTruth() const {
  std::error_code ec;
  return fs::is_regular_file(directory_ / kGroundTruth, ec);
}

Trajectory DatasetReader::GroundTruth() const {
  if (!HasGroundTruth()) core::ThrowInvalidInput((directory_ / kGroundTruth).string() + ": missing (no ground truth)");
  return ReadTum(directory_ / kGroundTruth);
}

std::string DatasetReader::Summary::Describe() const {
  std::ostringstream text;
  text << "valid: " << frames << " frames, " << encoder_samples << " encoder samples, " << groundtruth_poses
       << " ground-truth poses, " << std::fixed << std::setprecision(2) << duration_s << " s";
  if (skipped_frames + skipped_encoder_samples > 0) {
    text << "\n  skipped, not after the row before in time: " << skipped_frames << " frames, "
         << skipped_encoder_samples << " encoder samples";
  }
  return text.str();
}

DatasetReader::Summary DatasetReader::Validate() const {
  Summary summary;
  std::optional<core::Timestamp> first;
  std::optional<core::Timestamp> last;
  auto frames = Frames();
  while (const auto frame = frames.Next()) {
    ++summary.frames;
    if (!first) first = frame->time;
    last = frame->time;
  }
  auto encoders = Encoders();
  while (encoders.Next()) ++summary.encoder_samples;
  if (HasGroundTruth()) summary.groundtruth_poses = static_cast<std::int64_t>(GroundTruth().size());
  if (first && last) summary.duration_s = core::ToSeconds(*last - *first);
  summary.skipped_frames = skipped_frames_;
  summary.skipped_encoder_samples = skipped_encoder_samples_;
  return summary;
}

DatasetWriter::DatasetWriter(const fs::path& directory, const DatasetInfo& info, bool overwrite)
    : directory_(fs::absolute(directory)), info_(info), overwrite_(overwrite) {
  std::error_code ec;
  if (fs::exists(directory_, ec) && !overwrite_) {
    core::ThrowInvalidInput(directory_.string() + ": already exists (choose another output or allow overwriting)");
  }
  const std::string staging_prefix = "." + directory_.filename().string() + ".partial-";
  staging_ = directory_.parent_path() / (staging_prefix + std::to_string(::getpid()));
  // What a writer killed outright (SIGKILL, a power cut) left: its process is gone.
  for (const fs::directory_entry& entry : fs::directory_iterator(directory_.parent_path(), ec)) {
    const std::string name = entry.path().filename().string();
    if (name.rfind(staging_prefix, 0) != 0) continue;
    const std::string pid = name.substr(staging_prefix.size());
    if (pid.empty() || pid.find_first_not_of("0123456789") != std::string::npos || pid.size() > 9) continue;
    if (::kill(static_cast<pid_t>(std::stol(pid)), 0) != 0 && errno == ESRCH) fs::remove_all(entry.path(), ec);
  }
  ec.clear();
  fs::remove_all(staging_, ec);
  fs::create_directories(staging_ / kFramesDir, ec);
  fs::create_directories(staging_ / "encoders", ec);
  if (ec) core::ThrowRuntime(staging_.string() + ": cannot create (" + ec.message() + ")");
  frames_csv_.open(staging_ / kFramesCsv);
  encoders_csv_.open(staging_ / kEncodersCsv);
  if (!frames_csv_ || !encoders_csv_) core::ThrowRuntime(staging_.string() + ": cannot write");
  frames_csv_ << kFramesHeader << "\n";
  encoders_csv_ << ColumnsOf(info_.vehicle.kind).header << "\n";
}

DatasetWriter::~DatasetWriter() {
  if (!committed_) {
    std::error_code ec;
    frames_csv_.close();
    encoders_csv_.close();
    fs::remove_all(staging_, ec);
  }
}

void DatasetWriter::AddFrame(core::Timestamp time, const cv::Mat& image) {
  if (image.type() != CV_8UC1 || image.cols != info_.camera.width_px || image.rows != info_.camera.height_px) {
    core::ThrowInvalidInput("dataset writer: frame must be 8-bit grey " + std::to_string(info_.camera.width_px) + "x" +
                            std::to_string(info_.camera.height_px));
  }
  AddEncodedFrame(time, EncodeFrame(image));
}

std::vector<unsigned char> DatasetWriter::EncodeFrame(const cv::Mat& image) {
  std::vector<unsigned char> png;
  // OpenCV's speed-tuned PNG (no parameters: the SUB filter on every row, zlib's fastest level,
  // run-length matching). A compression level given explicitly makes libpng try all five row
  // filters on every row, which costs more than the compression: for 640x480 camera frames
  // (brick floor) this writes in 0.57 of the time of level 1 with Huffman-only coding, 8 % larger.
  if (!cv::imencode(".png", image, png)) {
    core::ThrowRuntime("dataset writer: cannot encode a frame as PNG");
  }
  return png;
}

void DatasetWriter::AddEncodedFrame(core::Timestamp time, const std::vector<unsigned char>& png) {
  if (last_frame_time_ && time <= *last_frame_time_) {
    core::ThrowInvalidInput("dataset writer: frame times must increase (" + std::to_string(time.nanoseconds()) + ")");
  }
  last_frame_time_ = time;
  const std::string name = FrameFileName(time);
  const fs::path file = staging_ / kFramesDir / name;
  core::WriteFile(file, std::string_view(reinterpret_cast<const char*>(png.data()), png.size()));
  frames_csv_ << time.nanoseconds() << "," << name << "\n";
}

void DatasetWriter::AddEncoderSample(const EncoderSample& sample) {
  if (last_encoder_time_ && sample.time <= *last_encoder_time_) {
    core::ThrowInvalidInput("dataset writer: encoder times must increase (" +
                            std::to_string(sample.time.nanoseconds()) + ")");
  }
  last_encoder_time_ = sample.time;
  const EncoderColumns columns = ColumnsOf(info_.vehicle.kind);
  encoders_csv_ << sample.time.nanoseconds();
  for (int i = 0; i < columns.count; ++i) encoders_csv_ << "," << sample.counts.*columns.fields[i];
  encoders_csv_ << "\n";
}

void DatasetWriter::SetGroundTruth(const Trajectory& world_from_vehicle) { groundtruth_ = world_from_vehicle; }

void DatasetWriter::AddFile(const std::filesystem::path& relative, std::string_view content) {
  const std::filesystem::path normal = relative.lexically_normal();
  if (relative.empty() || normal.is_absolute() || normal.begin()->string() == "..") {
    core::ThrowInvalidInput("dataset: extra file '" + relative.string() + "' must stay inside the dataset");
  }
  std::error_code ec;
  std::filesystem::create_directories((staging_ / normal).parent_path(), ec);
  core::WriteFile(staging_ / normal, content);
}

void DatasetWriter::Commit() {
  if (committed_) return;
  YAML::Emitter yaml;
  yaml.SetDoublePrecision(17);
  yaml << YAML::BeginMap;
  yaml << YAML::Key << "format_version" << YAML::Value << kFormatVersion;
  yaml << YAML::Key << "camera" << YAML::Value << YAML::BeginMap;
  yaml << YAML::Key << "width_px" << YAML::Value << info_.camera.width_px;
  yaml << YAML::Key << "height_px" << YAML::Value << info_.camera.height_px;
  yaml << YAML::Key << "mm_per_px" << YAML::Value << info_.camera.mm_per_px;
  yaml << YAML::Key << "vehicle_from_camera" << YAML::Value << YAML::Flow << YAML::BeginMap;
  yaml << YAML::Key << "x_mm" << YAML::Value << info_.camera.vehicle_from_camera.x_mm();
  yaml << YAML::Key << "y_mm" << YAML::Value << info_.camera.vehicle_from_camera.y_mm();
  yaml << YAML::Key << "yaw_rad" << YAML::Value << info_.camera.vehicle_from_camera.yaw_rad();
  yaml << YAML::EndMap << YAML::EndMap;
  yaml << YAML::Key << "vehicle" << YAML::Value << YAML::BeginMap;
  const core::WheelGeometry& v = info_.vehicle;
  if (v.kind == core::DriveKind::kTricycle) {
    yaml << YAML::Key << "kind" << YAML::Value << core::ToString(v.kind);
    yaml << YAML::Key << "drive_wheel_radius_mm" << YAML::Value << v.drive_wheel_radius_mm;
    yaml << YAML::Key << "wheelbase_mm" << YAML::Value << v.wheelbase_mm;
    yaml << YAML::Key << "ticks_per_revolution" << YAML::Value << v.ticks_per_revolution;
    yaml << YAML::Key << "steering_ticks_per_revolution" << YAML::Value << v.steering_ticks_per_revolution;
    yaml << YAML::Key << "steering_offset_deg" << YAML::Value << v.steering_offset_deg;
  } else if (v.kind == core::DriveKind::kMecanum) {
    yaml << YAML::Key << "kind" << YAML::Value << core::ToString(v.kind);
    yaml << YAML::Key << "mecanum_wheel_radius_mm" << YAML::Value << v.mecanum_wheel_radius_mm;
    yaml << YAML::Key << "track_width_mm" << YAML::Value << v.track_width_mm;
    yaml << YAML::Key << "wheelbase_mm" << YAML::Value << v.wheelbase_mm;
    yaml << YAML::Key << "ticks_per_revolution" << YAML::Value << v.ticks_per_revolution;
  } else {  // the kind is the default: left out, as datasets from before tricycles have it
    yaml << YAML::Key << "left_wheel_radius_mm" << YAML::Value << v.left_wheel_radius_mm;
    yaml << YAML::Key << "right_wheel_radius_mm" << YAML::Value << v.right_wheel_radius_mm;
    yaml << YAML::Key << "track_width_mm" << YAML::Value << v.track_width_mm;
    yaml << YAML::Key << "ticks_per_revolution" << YAML::Value << v.ticks_per_revolution;
  }
  yaml << YAML::EndMap;
  if (!info_.provenance.empty()) {
    yaml << YAML::Key << "provenance" << YAML::Value << YAML::BeginMap;
    for (const auto& [key, value] : info_.provenance) yaml << YAML::Key << key << YAML::Value << value;
    yaml << YAML::EndMap;
  }
  yaml << YAML::EndMap;
  core::WriteFile(staging_ / "dataset.yaml", std::string(yaml.c_str()) + "\n");
  frames_csv_.close();
  encoders_csv_.close();
  if (!frames_csv_ || !encoders_csv_) {
    core::ThrowRuntime(staging_.string() + ": cannot write the CSV files (" + core::WriteErrorText(errno) + ")");
  }
  if (groundtruth_) {
    std::error_code ec;
    fs::create_directories(staging_ / "groundtruth", ec);
    WriteTum(staging_ / kGroundTruth, *groundtruth_);
  }

  std::error_code ec;
  const fs::path old = directory_.parent_path() / ("." + directory_.filename().string() + ".old-" + std::to_string(::getpid()));
  const bool replacing = fs::exists(directory_, ec);
  if (replacing) {
    fs::rename(directory_, old, ec);
    if (ec) core::ThrowRuntime(directory_.string() + ": cannot move the previous dataset aside (" + ec.message() + ")");
  }
  fs::rename(staging_, directory_, ec);
  if (ec) {
    if (replacing) fs::rename(old, directory_, ec);
    core::ThrowRuntime(directory_.string() + ": cannot move the new dataset into place");
  }
  committed_ = true;
  if (replacing) fs::remove_all(old, ec);
}

DatasetInfo DerivedInfo(const DatasetReader& reader, const CameraInfo& camera, const std::string& note) {
  DatasetInfo info = reader.info();
  info.camera = camera;
  info.provenance["calibration"] = note;
  return info;
}

namespace {

// The provenance keys of a kind's three true wheel values, and where they go.
struct TruthKeys {
  const char* keys[3];
  double core::WheelGeometry::*fields[3];
};
TruthKeys TruthKeysOf(core::DriveKind kind) {
  using W = core::WheelGeometry;
  if (kind == core::DriveKind::kTricycle) {
    return {{"truth_drive_wheel_radius_mm", "truth_wheelbase_mm", "truth_steering_offset_deg"},
            {&W::drive_wheel_radius_mm, &W::wheelbase_mm, &W::steering_offset_deg}};
  }
  if (kind == core::DriveKind::kMecanum) {
    return {{"truth_mecanum_wheel_radius_mm", "truth_track_width_mm", "truth_wheelbase_mm"},
            {&W::mecanum_wheel_radius_mm, &W::track_width_mm, &W::wheelbase_mm}};
  }
  return {{"truth_left_wheel_radius_mm", "truth_right_wheel_radius_mm", "truth_track_width_mm"},
          {&W::left_wheel_radius_mm, &W::right_wheel_radius_mm, &W::track_width_mm}};
}

}  // namespace

void RecordVehicleTruth(const VehicleTruth& truth, DatasetInfo* info) {
  const auto number = [](double value) {
    std::ostringstream out;
    out.precision(9);
    out << value;
    return out.str();
  };
  const core::Pose2& x = truth.vehicle_from_camera;
  info->provenance["truth_vehicle_from_camera"] = number(x.x_mm()) + " " + number(x.y_mm()) + " " + number(x.yaw_rad());
  const TruthKeys keys = TruthKeysOf(truth.wheels.kind);
  for (int i = 0; i < 3; ++i) info->provenance[keys.keys[i]] = number(truth.wheels.*keys.fields[i]);
}

std::optional<VehicleTruth> RecordedVehicleTruth(const DatasetInfo& info) {
  // The truth of the dataset's kind of vehicle.
  const TruthKeys wheel_keys = TruthKeysOf(info.vehicle.kind);
  const char* const keys[] = {"truth_vehicle_from_camera", wheel_keys.keys[0], wheel_keys.keys[1], wheel_keys.keys[2]};
  const std::size_t values[] = {3, 1, 1, 1};
  double v[6] = {};
  std::size_t next = 0;
  for (std::size_t k = 0; k < 4; ++k) {
    const auto found = info.provenance.find(keys[k]);
    if (found == info.provenance.end()) return std::nullopt;
    std::istringstream in(found->second);
    for (std::size_t i = 0; i < values[k]; ++i) {
      if (!(in >> v[next++])) {
        core::ThrowInvalidInput(std::string("dataset provenance ") + keys[k] + ": expected " +
                                (values[k] == 1 ? "a number" : "three numbers") + ", got '" + found->second + "'");
      }
    }
  }
  VehicleTruth truth;
  truth.vehicle_from_camera = core::Pose2(v[0], v[1], v[2]);
  truth.wheels = info.vehicle;
  for (int i = 0; i < 3; ++i) truth.wheels.*wheel_keys.fields[i] = v[3 + i];
  return truth;
}

void WritePng(const std::filesystem::path& file, const cv::Mat& image) {
  std::vector<unsigned char> png;
  if (!cv::imencode(".png", image, png)) core::ThrowRuntime(file.string() + ": cannot encode PNG");
  core::WriteFileAtomically(file, std::string_view(reinterpret_cast<const char*>(png.data()), png.size()));
}

void CopyEncodersAndTruth(const DatasetReader& reader, DatasetWriter* writer) {
  for (auto encoders = reader.Encoders(); auto sample = encoders.Next();) writer->AddEncoderSample(*sample);
  if (reader.HasGroundTruth()) writer->SetGroundTruth(reader.GroundTruth());
}

}  // namespace mosaicloc::dataset
