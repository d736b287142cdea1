#include "visp_calibration.hpp"

#include <cmath>
#include <exception>
#include <iostream>
#include <sstream>

#include <visp3/core/vpCameraParameters.h>
#include <visp3/core/vpException.h>
#include <visp3/core/vpHomogeneousMatrix.h>
#include <visp3/core/vpImagePoint.h>
#include <visp3/core/vpXmlParserCamera.h>
#include <visp3/vision/vpCalibration.h>

namespace mosaicloc::calibration::detail {
namespace {

// ViSP works in metres; the board is in millimetres.
constexpr double kMetresPerMm = 1e-3;
constexpr double kGain = 0.8;

// Reprojection RMS of one view, sqrt(mean(du^2 + dv^2)), with ViSP's distortion model.
double ViewRms(const VispViewPoints& view, const vpHomogeneousMatrix& camera_from_board, const vpCameraParameters& cam) {
  double sum = 0.0;
  for (std::size_t k = 0; k < view.object_mm.size(); ++k) {
    const Eigen::Vector3d& p = view.object_mm[k];
    const double X = kMetresPerMm * p.x(), Y = kMetresPerMm * p.y(), Z = kMetresPerMm * p.z();
    const double xc = camera_from_board[0][0] * X + camera_from_board[0][1] * Y + camera_from_board[0][2] * Z +
                      camera_from_board[0][3];
    const double yc = camera_from_board[1][0] * X + camera_from_board[1][1] * Y + camera_from_board[1][2] * Z +
                      camera_from_board[1][3];
    const double zc = camera_from_board[2][0] * X + camera_from_board[2][1] * Y + camera_from_board[2][2] * Z +
                      camera_from_board[2][3];
    const double x = xc / zc, y = yc / zc;
    const double d = 1.0 + cam.get_kud() * (x * x + y * y);
    const double du = cam.get_u0() + cam.get_px() * x * d - view.image_px[k].x();
    const double dv = cam.get_v0() + cam.get_py() * y * d - view.image_px[k].y();
    sum += du * du + dv * dv;
  }
  return std::sqrt(sum / static_cast<double>(view.object_mm.size()));
}

}  // namespace

VispCalibrationAnswer CalibrateWithVisp(const std::vector<VispViewPoints>& views, const VispCameraModel& initial) {
  VispCalibrationAnswer answer;
  try {
    // Virtual visual servoing moves by gain x the Gauss-Newton step; ViSP's default (0.25)
    // needs hundreds of iterations for a 1e-10 convergence threshold.
    vpCalibration::setLambda(kGain);
    std::vector<vpCalibration> table;
    table.reserve(views.size());
    for (const VispViewPoints& view : views) {
      vpCalibration calibration;
      calibration.clearPoint();
      for (std::size_t k = 0; k < view.object_mm.size(); ++k) {
        // vpImagePoint is (i = row, j = column).
        vpImagePoint ip(view.image_px[k].y(), view.image_px[k].x());
        calibration.addPoint(kMetresPerMm * view.object_mm[k].x(), kMetresPerMm * view.object_mm[k].y(),
                             kMetresPerMm * view.object_mm[k].z(), ip);
      }
      // The pose of this view from the initial guess; the guess itself is not changed by
      // the views one by one, only by the joint refinement below.
      vpCameraParameters guess;
      guess.initPersProjWithoutDistortion(initial.fx_px, initial.fy_px, initial.cx_px, initial.cy_px);
      vpHomogeneousMatrix camera_from_board;
      if (calibration.computeCalibration(vpCalibration::CALIB_VIRTUAL_VS, camera_from_board, guess, false) !=
          0) {
        answer.error = "ViSP could not estimate the pose of one view";
        return answer;
      }
      table.push_back(calibration);
    }
    vpCameraParameters cam;
    cam.initPersProjWithoutDistortion(initial.fx_px, initial.fy_px, initial.cx_px, initial.cy_px);
    double rms = 0.0;
    if (vpCalibration::computeCalibrationMulti(vpCalibration::CALIB_VIRTUAL_VS, table, cam, rms, false) != 0) {
      answer.error = "ViSP's calibration without distortion did not converge";
      return answer;
    }
    if (vpCalibration::computeCalibrationMulti(vpCalibration::CALIB_VIRTUAL_VS_DIST, table, cam, rms, false) != 0) {
      answer.error = "ViSP's calibration with distortion did not converge";
      return answer;
    }
    answer.camera = {cam.get_px(), cam.get_py(), cam.get_u0(), cam.get_v0(), cam.get_kud(), cam.get_kdu()};
    double sum = 0.0;
    std::size_t count = 0;
    for (std::size_t v = 0; v < views.size(); ++v) {
      const double view_rms = ViewRms(views[v], table[v].cMo_dist, cam);
      answer.view_rms_px.push_back(view_rms);
      sum += view_rms * view_rms * static_cast<double>(views[v].object_mm.size());
      count += views[v].object_mm.size();
    }
    answer.rms_px = std::sqrt(sum / static_cast<double>(count));
    answer.ok = std::isfinite(answer.rms_px) && answer.camera.fx_px > 0.0 && answer.camera.fy_px > 0.0;
    if (!answer.ok) answer.error = "ViSP's calibration gave a degenerate camera";
  } catch (const vpException& e) {
    answer.ok = false;
    answer.error = std::string("ViSP: ") + e.getMessage();
  } catch (const std::exception& e) {
    answer.ok = false;
    answer.error = std::string("ViSP: ") + e.what();
  }
  return answer;
}

std::string SaveVispXml(const std::string& file, const VispCameraModel& camera, const std::string& camera_name,
                        int width_px, int height_px, const std::string& note) {
  try {
    vpCameraParameters cam;
    cam.initPersProjWithDistortion(camera.fx_px, camera.fy_px, camera.cx_px, camera.cy_px, camera.kud, camera.kdu);
    vpXmlParserCamera parser;
    if (parser.save(cam, file, camera_name, static_cast<unsigned>(width_px), static_cast<unsigned>(height_px), note) !=
        vpXmlParserCamera::SEQUENCE_OK) {
      return "vpXmlParserCamera could not save the camera";
    }
  } catch (const vpException& e) {
    return std::string("ViSP: ") + e.getMessage();
  }
  return {};
}

std::string LoadVispXml(const std::string& file, const std::string& camera_name, VispCameraModel* camera,
                        int* width_px, int* height_px) {
  try {
    vpCameraParameters cam;
    vpXmlParserCamera parser;
    // The parser announces the camera it found on standard output, which belongs to the
    // program: silence it for the call.
    std::ostringstream chatter;
    std::streambuf* const stdout_buffer = std::cout.rdbuf(chatter.rdbuf());
    const int status = parser.parse(cam, file, camera_name, vpCameraParameters::perspectiveProjWithDistortion);
    std::cout.rdbuf(stdout_buffer);
    if (status != vpXmlParserCamera::SEQUENCE_OK) {
      return camera_name.empty() ? "no camera with distortion in it"
                                 : "no camera named '" + camera_name + "' with distortion in it";
    }
    *camera = {cam.get_px(), cam.get_py(), cam.get_u0(), cam.get_v0(), cam.get_kud(), cam.get_kdu()};
    *width_px = static_cast<int>(parser.getWidth());
    *height_px = static_cast<int>(parser.getHeight());
  } catch (const vpException& e) {
    return std::string("ViSP: ") + e.getMessage();
  }
  return {};
}

}  // namespace mosaicloc::calibration::detail
