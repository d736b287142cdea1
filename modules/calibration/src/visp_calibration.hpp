#pragma once

// The plain interface of the one camera file that includes ViSP (compiled as C++17:
// ViSP 3.5's headers do not compile as C++20). No ViSP type crosses it.

#include <string>
#include <vector>

#include <Eigen/Core>

namespace mosaicloc::calibration::detail {

struct VispViewPoints {
  std::vector<Eigen::Vector3d> object_mm;  ///< board frame
  std::vector<Eigen::Vector2d> image_px;
};

struct VispCameraModel {
  double fx_px = 0.0, fy_px = 0.0, cx_px = 0.0, cy_px = 0.0, kud = 0.0, kdu = 0.0;
};

struct VispCalibrationAnswer {
  bool ok = false;
  std::string error;
  VispCameraModel camera;
  std::vector<double> view_rms_px;
  double rms_px = 0.0;
};

/// vpCalibration over all views from `initial` (no distortion), see CalibrateIntrinsics.
VispCalibrationAnswer CalibrateWithVisp(const std::vector<VispViewPoints>& views, const VispCameraModel& initial);

/// vpXmlParserCamera save to a new file / parse. Empty string on success, else the reason.
std::string SaveVispXml(const std::string& file, const VispCameraModel& camera, const std::string& camera_name,
                        int width_px, int height_px, const std::string& note);
std::string LoadVispXml(const std::string& file, const std::string& camera_name, VispCameraModel* camera,
                        int* width_px, int* height_px);

}  // namespace mosaicloc::calibration::detail
