#include "mosaicloc/calibration/board_images.hpp"

#include <glob.h>

#include <algorithm>
#include <cmath>

#include <opencv2/imgcodecs.hpp>

#include "mosaicloc/calibration/board_detection.hpp"
#include "mosaicloc/core/error.hpp"
#include "mosaicloc/dataset/dataset.hpp"

namespace mosaicloc::calibration {

std::vector<std::filesystem::path> MatchImages(const std::string& pattern) {
  glob_t found{};
  const int status = ::glob(pattern.c_str(), 0, nullptr, &found);
  std::vector<std::filesystem::path> files;
  if (status == 0) {
    for (std::size_t i = 0; i < found.gl_pathc; ++i) {
      if (std::filesystem::is_regular_file(found.gl_pathv[i])) files.emplace_back(found.gl_pathv[i]);
    }
  }
  ::globfree(&found);
  if (files.empty()) core::ThrowInvalidInput("no images match '" + pattern + "'");
  std::sort(files.begin(), files.end());
  return files;
}

cv::Mat ReadGreyImage(const std::filesystem::path& file) {
  const cv::Mat image = cv::imread(file.string(), cv::IMREAD_GRAYSCALE);
  if (image.empty()) core::ThrowInvalidInput(file.string() + ": cannot be read as an image");
  return image;
}

std::vector<BoardView> DetectBoardInImages(const std::vector<std::filesystem::path>& files,
                                           const camera::BoardSpec& board, int* width, int* height) {
  std::vector<BoardView> views;
  for (const std::filesystem::path& file : files) {
    const cv::Mat image = ReadGreyImage(file);
    if (views.empty()) {
      *width = image.cols;
      *height = image.rows;
    } else if (image.cols != *width || image.rows != *height) {
      core::ThrowInvalidInput(file.string() + ": " + std::to_string(image.cols) + "x" + std::to_string(image.rows) +
                              " differs from the first image's " + std::to_string(*width) + "x" +
                              std::to_string(*height));
    }
    BoardView view;
    view.name = file.filename().string();
    if (const auto detection = DetectBoard(image, board)) view.detection = *detection;
    views.push_back(std::move(view));
  }
  return views;
}

namespace {

cv::Mat Rectified(const std::filesystem::path& file, const Rectifier& rectifier) {
  cv::Mat ideal;
  if (!rectifier.Rectify(ReadGreyImage(file), &ideal)) {
    core::ThrowInvalidInput(file.string() + ": not the calibrated raw size " +
                            std::to_string(rectifier.calibration().intrinsics.width_px) + "x" +
                            std::to_string(rectifier.calibration().intrinsics.height_px));
  }
  return ideal;
}

}  // namespace

void RectifyImages(const std::vector<std::filesystem::path>& files, const Rectifier& rectifier,
                   const std::filesystem::path& out_dir) {
  std::vector<cv::Mat> rectified;
  for (const std::filesystem::path& file : files) rectified.push_back(Rectified(file, rectifier));
  std::filesystem::create_directories(out_dir);
  for (std::size_t i = 0; i < files.size(); ++i) {
    dataset::WritePng(out_dir / files[i].filename().replace_extension(".png"), rectified[i]);
  }
}

IdealBoardMeasurement MeasureRectifiedBoard(const std::filesystem::path& file, const Rectifier& rectifier,
                                            const camera::BoardSpec& board) {
  const auto detection = DetectBoard(Rectified(file, rectifier), board);
  if (!detection) core::ThrowInvalidInput(file.string() + ": board " + board.ToString() + " not found once rectified");
  return MeasureIdealBoard(*detection, board, rectifier.calibration().ideal);
}

ImagesIntrinsics CalibrateIntrinsicsFromImages(const std::string& pattern, const camera::BoardSpec& board,
                                               const std::filesystem::path& camera_xml, const std::string& camera_name) {
  const std::vector<std::filesystem::path> files = MatchImages(pattern);
  ImagesIntrinsics out;
  const std::vector<BoardView> views = DetectBoardInImages(files, board, &out.width_px, &out.height_px);
  if (std::none_of(views.begin(), views.end(), [](const auto& v) { return !v.detection.points_px.empty(); })) {
    core::ThrowInvalidInput("board " + board.ToString() + " not found in any of the " + std::to_string(files.size()) +
                            " images matching '" + pattern + "'");
  }
  out.result = CalibrateIntrinsics(views, board, out.width_px, out.height_px, {});
  WriteVispCameraXml(camera_xml, out.result.visp.intrinsics, camera_name,
                     "mosaicloc calibrate intrinsics, board " + board.ToString() + ", " +
                         std::to_string(out.result.used.size()) + " images, RMS " +
                         std::to_string(out.result.visp.rms_px) + " px");
  return out;
}

GroundResult CalibrateGroundFromImages(const std::string& pattern, const camera::BoardSpec& board,
                                       const std::filesystem::path& camera_xml, const std::string& camera_name,
                                       const GroundOptions& options, const std::filesystem::path& out) {
  const Intrinsics intrinsics = ReadVispCameraXml(camera_xml, camera_name);
  std::string why;
  if (!options.Check(&why)) core::ThrowInvalidInput(why);
  const std::vector<std::filesystem::path> files = MatchImages(pattern);
  int width = 0, height = 0;
  const std::vector<BoardView> views = DetectBoardInImages(files, board, &width, &height);
  if (width != intrinsics.width_px || height != intrinsics.height_px) {
    core::ThrowInvalidInput(files.front().string() + ": images are " + std::to_string(width) + "x" +
                            std::to_string(height) + " but " + camera_xml.string() + " is for " +
                            std::to_string(intrinsics.width_px) + "x" + std::to_string(intrinsics.height_px));
  }
  GroundResult result = CalibrateGround(views, board, intrinsics, options);
  WriteGroundCalibration(out, result.calibration,
                         "mosaicloc calibrate ground, board " + board.ToString() + ", " + std::to_string(views.size()) +
                             " images, intrinsics " + camera_xml.filename().string());
  return result;
}

RectificationCheck VerifyRectification(const std::string& pattern, const std::filesystem::path& ground,
                                       const camera::BoardSpec& board) {
  const Rectifier rectifier(ReadGroundCalibration(ground));
  RectificationCheck check;
  for (const std::filesystem::path& file : MatchImages(pattern)) {
    check.images.emplace_back(file, MeasureRectifiedBoard(file, rectifier, board));
    check.worst_scale_error = std::max(check.worst_scale_error, std::abs(check.images.back().second.scale_error));
  }
  return check;
}

}  // namespace mosaicloc::calibration
