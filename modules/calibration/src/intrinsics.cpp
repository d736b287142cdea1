#include "mosaicloc/calibration/intrinsics.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>
#include <system_error>

#include <unistd.h>

#include <opencv2/calib3d.hpp>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/core/file.hpp"
#include "visp_calibration.hpp"

namespace mosaicloc::calibration {
namespace {

IntrinsicsEstimate CalibrateWithOpenCv(const std::vector<const BoardView*>& views, const camera::BoardSpec& board,
                                       int width_px, int height_px) {
  std::vector<cv::Point3f> object;
  for (const Eigen::Vector3d& p : board.FeaturePoints()) {
    object.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z()));
  }
  std::vector<std::vector<cv::Point3f>> object_points(views.size(), object);
  std::vector<std::vector<cv::Point2f>> image_points;
  for (const BoardView* view : views) {
    std::vector<cv::Point2f> points;
    for (const Eigen::Vector2d& p : view->detection.points_px) {
      points.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()));
    }
    image_points.push_back(std::move(points));
  }
  cv::Mat camera_matrix, distortion, std_intrinsics, std_extrinsics, per_view;
  std::vector<cv::Mat> rvecs, tvecs;
  const int flags = cv::CALIB_FIX_K2 | cv::CALIB_FIX_K3 | cv::CALIB_ZERO_TANGENT_DIST;
  IntrinsicsEstimate estimate;
  try {
    estimate.rms_px = cv::calibrateCamera(object_points, image_points, cv::Size(width_px, height_px), camera_matrix,
                                          distortion, rvecs, tvecs, std_intrinsics, std_extrinsics, per_view, flags,
                                          cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 100, 1e-12));
  } catch (const cv::Exception& e) {
    core::ThrowRuntime(std::string("OpenCV calibrateCamera failed: ") + e.what());
  }
  Intrinsics& k = estimate.intrinsics;
  k.width_px = width_px;
  k.height_px = height_px;
  k.fx_px = camera_matrix.at<double>(0, 0);
  k.fy_px = camera_matrix.at<double>(1, 1);
  k.cx_px = camera_matrix.at<double>(0, 2);
  k.cy_px = camera_matrix.at<double>(1, 2);
  k.kud = distortion.at<double>(0);
  k.kdu = 0.0;  // OpenCV has no closed-form inverse model
  for (int i = 0; i < per_view.rows; ++i) estimate.view_rms_px.push_back(per_view.at<double>(i));
  return estimate;
}

detail::VispCalibrationAnswer RunVisp(const std::vector<const BoardView*>& views, const camera::BoardSpec& board,
                                      int width_px, int height_px) {
  std::vector<detail::VispViewPoints> points;
  const std::vector<Eigen::Vector3d> object = board.FeaturePoints();
  for (const BoardView* view : views) points.push_back({object, view->detection.points_px});
  // Image centre and a 60-degree horizontal field of view: f = (w / 2) / tan(30 deg).
  const double f = 0.5 * width_px / std::tan(30.0 * M_PI / 180.0);
  const detail::VispCameraModel initial{f, f, 0.5 * (width_px - 1), 0.5 * (height_px - 1), 0.0, 0.0};
  return detail::CalibrateWithVisp(points, initial);
}

std::string Format(double value) {
  char text[32];
  std::snprintf(text, sizeof(text), "%.3f", value);
  return text;
}

}  // namespace

bool Intrinsics::Check(std::string* why) const {
  if (width_px < 8 || height_px < 8) {
    *why = "intrinsics image size must be at least 8x8 pixels";
    return false;
  }
  if (!(fx_px > 0.0) || !(fy_px > 0.0) || !std::isfinite(fx_px) || !std::isfinite(fy_px)) {
    *why = "intrinsics fx_px and fy_px must be positive";
    return false;
  }
  if (!std::isfinite(cx_px) || !std::isfinite(cy_px) || !std::isfinite(kud) || !std::isfinite(kdu)) {
    *why = "intrinsics cx_px, cy_px, kud and kdu must be finite";
    return false;
  }
  return true;
}

bool IntrinsicsOptions::Check(std::string* why) const {
  if (!(outlier_factor > 1.0)) {
    *why = "intrinsics outlier_factor must be > 1";
    return false;
  }
  if (!(outlier_min_rms_px >= 0.0)) {
    *why = "intrinsics outlier_min_rms_px must be >= 0";
    return false;
  }
  if (min_views < 2) {
    *why = "intrinsics min_views must be >= 2";
    return false;
  }
  return true;
}

IntrinsicsResult CalibrateIntrinsics(const std::vector<BoardView>& views, const camera::BoardSpec& board, int width_px,
                                     int height_px, const IntrinsicsOptions& options) {
  std::string why;
  if (!options.Check(&why) || !board.Check(&why)) core::ThrowInvalidInput(why);
  if (width_px < 8 || height_px < 8) core::ThrowInvalidInput("calibration images must be at least 8x8 pixels");
  IntrinsicsResult result;
  std::vector<const BoardView*> usable;
  for (const BoardView& view : views) {
    ViewReport report;
    report.name = view.name;
    if (static_cast<int>(view.detection.points_px.size()) != board.FeatureCount()) {
      report.rejected_because = "board not found";
    } else {
      usable.push_back(&view);
    }
    result.views.push_back(report);
  }
  const auto report_of = [&](const BoardView* view) -> ViewReport& {
    return result.views[static_cast<std::size_t>(view - views.data())];
  };
  const auto too_few = [&](const std::string& stage) {
    std::string message = "only " + std::to_string(usable.size()) + " usable calibration image(s) " + stage +
                          ", need " + std::to_string(options.min_views);
    std::string rejected;
    for (const ViewReport& report : result.views) {
      if (!report.rejected_because.empty()) {
        rejected += (rejected.empty() ? "" : ", ") + report.name + " (" + report.rejected_because + ")";
      }
    }
    if (!rejected.empty()) message += "; rejected: " + rejected;
    core::ThrowInvalidInput(message);
  };
  if (static_cast<int>(usable.size()) < options.min_views) too_few("with the board found");

  detail::VispCalibrationAnswer first = RunVisp(usable, board, width_px, height_px);
  if (!first.ok) core::ThrowRuntime("intrinsic calibration failed: " + first.error);
  for (std::size_t i = 0; i < usable.size(); ++i) report_of(usable[i]).first_pass_rms_px = first.view_rms_px[i];

  // Outliers against the median view, dropped once.
  std::vector<double> sorted = first.view_rms_px;
  std::nth_element(sorted.begin(), sorted.begin() + static_cast<long>(sorted.size() / 2), sorted.end());
  const double median = sorted[sorted.size() / 2];
  const double limit = std::max(options.outlier_factor * median, options.outlier_min_rms_px);
  std::vector<const BoardView*> kept;
  for (std::size_t i = 0; i < usable.size(); ++i) {
    if (first.view_rms_px[i] > limit) {
      report_of(usable[i]).rejected_because = "reprojection RMS " + Format(first.view_rms_px[i]) +
                                              " px is an outlier (median " + Format(median) + " px, limit " +
                                              Format(limit) + " px)";
    } else {
      kept.push_back(usable[i]);
    }
  }
  detail::VispCalibrationAnswer final_answer = std::move(first);
  if (kept.size() != usable.size()) {
    usable = kept;
    if (static_cast<int>(usable.size()) < options.min_views) too_few("after rejecting outliers");
    final_answer = RunVisp(usable, board, width_px, height_px);
    if (!final_answer.ok) core::ThrowRuntime("intrinsic calibration failed: " + final_answer.error);
  }
  for (const BoardView* view : usable) {
    report_of(view).used = true;
    result.used.push_back(view->name);
  }
  Intrinsics& k = result.visp.intrinsics;
  k.width_px = width_px;
  k.height_px = height_px;
  k.fx_px = final_answer.camera.fx_px;
  k.fy_px = final_answer.camera.fy_px;
  k.cx_px = final_answer.camera.cx_px;
  k.cy_px = final_answer.camera.cy_px;
  k.kud = final_answer.camera.kud;
  k.kdu = final_answer.camera.kdu;
  result.visp.rms_px = final_answer.rms_px;
  result.visp.view_rms_px = final_answer.view_rms_px;
  result.opencv = CalibrateWithOpenCv(usable, board, width_px, height_px);
  for (std::size_t i = 0; i < usable.size(); ++i) {
    report_of(usable[i]).visp_rms_px = result.visp.view_rms_px.at(i);
    report_of(usable[i]).opencv_rms_px = result.opencv.view_rms_px.at(i);
  }
  return result;
}

void WriteVispCameraXml(const std::filesystem::path& file, const Intrinsics& intrinsics,
                        const std::string& camera_name, const std::string& note) {
  std::string why;
  if (!intrinsics.Check(&why)) core::ThrowInvalidInput(file.string() + ": " + why);
  // vpXmlParserCamera adds to an existing file (and refuses a camera already in it), so it
  // writes a fresh scratch file whose content then replaces `file` atomically.
  const std::filesystem::path directory = file.has_parent_path() ? file.parent_path() : std::filesystem::path(".");
  const std::filesystem::path scratch =
      directory / ("." + file.filename().string() + ".visp-" + std::to_string(::getpid()) + ".xml");
  std::error_code ignored;
  std::filesystem::remove(scratch, ignored);
  const detail::VispCameraModel model{intrinsics.fx_px, intrinsics.fy_px, intrinsics.cx_px,
                                      intrinsics.cy_px, intrinsics.kud,   intrinsics.kdu};
  const std::string error =
      detail::SaveVispXml(scratch.string(), model, camera_name, intrinsics.width_px, intrinsics.height_px, note);
  std::string content;
  if (error.empty()) {
    std::ifstream in(scratch, std::ios::binary);
    std::ostringstream buffer;
    buffer << in.rdbuf();
    content = buffer.str();
  }
  std::filesystem::remove(scratch, ignored);
  if (!error.empty() || content.empty()) {
    core::ThrowRuntime(file.string() + ": cannot write the camera XML: " + (error.empty() ? "empty output" : error));
  }
  core::WriteFileAtomically(file, content);
}

Intrinsics ReadVispCameraXml(const std::filesystem::path& file, const std::string& camera_name) {
  if (!std::filesystem::is_regular_file(file)) core::ThrowInvalidInput(file.string() + ": no such camera XML file");
  std::string name = camera_name;
  if (name.empty()) {
    // vpXmlParserCamera needs a name: take the first camera's.
    std::ifstream in(file);
    std::ostringstream buffer;
    buffer << in.rdbuf();
    const std::string text = buffer.str();
    const std::size_t begin = text.find("<name>"), end = text.find("</name>");
    if (begin != std::string::npos && end != std::string::npos && end > begin) {
      name = text.substr(begin + 6, end - begin - 6);
      name.erase(0, name.find_first_not_of(" \t\n"));
      name.erase(name.find_last_not_of(" \t\n") + 1);
    }
    if (name.empty()) core::ThrowInvalidInput(file.string() + ": no camera in it (not a ViSP camera XML?)");
  }
  detail::VispCameraModel model;
  Intrinsics intrinsics;
  const std::string error =
      detail::LoadVispXml(file.string(), name, &model, &intrinsics.width_px, &intrinsics.height_px);
  if (!error.empty()) core::ThrowInvalidInput(file.string() + ": " + error);
  intrinsics.fx_px = model.fx_px;
  intrinsics.fy_px = model.fy_px;
  intrinsics.cx_px = model.cx_px;
  intrinsics.cy_px = model.cy_px;
  intrinsics.kud = model.kud;
  intrinsics.kdu = model.kdu;
  std::string why;
  if (!intrinsics.Check(&why)) core::ThrowInvalidInput(file.string() + ": " + why);
  return intrinsics;
}

Eigen::Vector2d ProjectWithDistortion(const Intrinsics& k, const Eigen::Vector3d& point_optical) {
  const double x = point_optical.x() / point_optical.z(), y = point_optical.y() / point_optical.z();
  const double d = 1.0 + k.kud * (x * x + y * y);
  return {k.cx_px + k.fx_px * x * d, k.cy_px + k.fy_px * y * d};
}

Eigen::Vector2d UndistortToNormalized(const Intrinsics& k, const Eigen::Vector2d& pixel) {
  const Eigen::Vector2d distorted((pixel.x() - k.cx_px) / k.fx_px, (pixel.y() - k.cy_px) / k.fy_px);
  // Newton on f(r) = r (1 + kud r^2) - r_d along the unchanged radial direction.
  const double r_d = distorted.norm();
  if (r_d < 1e-15) return distorted;
  double r = r_d;
  for (int i = 0; i < 30; ++i) {
    const double f = r * (1.0 + k.kud * r * r) - r_d;
    const double df = 1.0 + 3.0 * k.kud * r * r;
    if (df <= 1e-6) break;
    const double step = f / df;
    r -= step;
    if (std::abs(step) < 1e-15) break;
  }
  return distorted * (r / r_d);
}

}  // namespace mosaicloc::calibration
