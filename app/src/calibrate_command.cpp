// mosaicloc calibrate: the installation steps that make a vehicle's camera ideal
// (tutorials/calibration): print a board, calibrate the intrinsics, the ground plane and the
// camera's place on the vehicle, rectify, verify.
#include <glob.h>

#include <algorithm>
#include <chrono>
#include <array>
#include <deque>
#include <optional>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "commands.hpp"
#include "mosaicloc/camera/board.hpp"
#include "mosaicloc/camera/flat_field.hpp"
#include "mosaicloc/camera/ground.hpp"
#include "mosaicloc/camera/intrinsics.hpp"
#include "mosaicloc/core/error.hpp"
#include "mosaicloc/core/file.hpp"
#include "mosaicloc/camera/vehicle_calibration.hpp"
#include "mosaicloc/core/log.hpp"
#include "mosaicloc/core/yaml.hpp"
#include "mosaicloc/dataset/dataset.hpp"
#include "mosaicloc/sim/calibration_drive.hpp"
#include "mosaicloc/dataset/trajectory.hpp"
#include "mosaicloc/sim/raw_imaging.hpp"
#include "mosaicloc/sim/simulator.hpp"
#include "sim_config.hpp"
#include "mosaicloc/tracking/tracker.hpp"
#include "progress.hpp"

namespace mosaicloc::app {
namespace {

// Files matching a shell pattern, sorted; bad input if none.
std::vector<std::filesystem::path> Glob(const std::string& pattern) {
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

cv::Mat ReadGrey(const std::filesystem::path& file) {
  const cv::Mat image = cv::imread(file.string(), cv::IMREAD_GRAYSCALE);
  if (image.empty()) core::ThrowInvalidInput(file.string() + ": cannot be read as an image");
  return image;
}

void WritePng(const std::filesystem::path& file, const cv::Mat& image) {
  std::vector<unsigned char> png;
  if (!cv::imencode(".png", image, png)) core::ThrowRuntime(file.string() + ": cannot encode PNG");
  core::WriteFileAtomically(file, std::string_view(reinterpret_cast<const char*>(png.data()), png.size()));
}

// Detects the board in every image, all of the same size.
std::vector<camera::BoardView> DetectAll(const std::vector<std::filesystem::path>& files,
                                         const camera::BoardSpec& board, int* width, int* height) {
  std::vector<camera::BoardView> views;
  for (const std::filesystem::path& file : files) {
    const cv::Mat image = ReadGrey(file);
    if (views.empty()) {
      *width = image.cols;
      *height = image.rows;
    } else if (image.cols != *width || image.rows != *height) {
      core::ThrowInvalidInput(file.string() + ": " + std::to_string(image.cols) + "x" + std::to_string(image.rows) +
                              " differs from the first image's " + std::to_string(*width) + "x" +
                              std::to_string(*height));
    }
    camera::BoardView view;
    view.name = file.filename().string();
    if (const auto detection = camera::DetectBoard(image, board)) view.detection = *detection;
    views.push_back(std::move(view));
  }
  return views;
}

nlohmann::json IntrinsicsJson(const camera::IntrinsicsEstimate& e) {
  const camera::Intrinsics& k = e.intrinsics;
  return {{"fx_px", k.fx_px}, {"fy_px", k.fy_px}, {"cx_px", k.cx_px}, {"cy_px", k.cy_px},
          {"kud", k.kud},     {"kdu", k.kdu},     {"rms_px", e.rms_px}};
}

// ---- calibrate board -------------------------------------------------------------------

struct BoardArgs {
  std::string board = "chessboard:9x6:25mm";
  std::filesystem::path out;
  double px_per_mm = 300.0 / 25.4;
};

void RunBoard(const BoardArgs& args, const GlobalOptions& global) {
  const camera::BoardSpec board = camera::ParseBoardSpec(args.board);
  const cv::Mat image = camera::DrawBoard(board, args.px_per_mm);
  WritePng(args.out, image);
  const double width_mm = image.cols / args.px_per_mm, height_mm = image.rows / args.px_per_mm;
  if (global.json) {
    std::printf("%s\n", nlohmann::json{{"board", board.ToString()}, {"png", args.out.string()},
                                       {"width_mm", width_mm}, {"height_mm", height_mm}}
                            .dump(2)
                            .c_str());
  } else {
    std::printf("board %s: %s, %dx%d px, print at %.1f x %.1f mm (%.0f dpi) and check one square with a ruler\n",
                board.ToString().c_str(), args.out.string().c_str(), image.cols, image.rows, width_mm, height_mm,
                args.px_per_mm * 25.4);
  }
}

// ---- calibrate intrinsics --------------------------------------------------------------

struct IntrinsicsArgs {
  std::string images;
  std::string board;
  std::filesystem::path out;
  std::string camera_name = "floor";
};

void RunIntrinsics(const IntrinsicsArgs& args, const GlobalOptions& global) {
  const camera::BoardSpec board = camera::ParseBoardSpec(args.board);
  const std::vector<std::filesystem::path> files = Glob(args.images);
  int width = 0, height = 0;
  const std::vector<camera::BoardView> views = DetectAll(files, board, &width, &height);
  if (std::none_of(views.begin(), views.end(), [](const auto& v) { return !v.detection.points_px.empty(); })) {
    core::ThrowInvalidInput("board " + board.ToString() + " not found in any of the " + std::to_string(files.size()) +
                            " images matching '" + args.images + "'");
  }
  const camera::IntrinsicsResult result = camera::CalibrateIntrinsics(views, board, width, height, {});
  camera::WriteVispCameraXml(args.out, result.visp.intrinsics, args.camera_name,
                             "mosaicloc calibrate intrinsics, board " + board.ToString() + ", " +
                                 std::to_string(result.used.size()) + " images, RMS " +
                                 std::to_string(result.visp.rms_px) + " px");
  if (global.json) {
    nlohmann::json images = nlohmann::json::array();
    std::size_t used_index = 0;
    for (const camera::ViewReport& view : result.views) {
      nlohmann::json entry = {{"image", view.name}, {"used", view.used}};
      if (view.used) {
        entry["visp_rms_px"] = result.visp.view_rms_px[used_index];
        entry["opencv_rms_px"] = result.opencv.view_rms_px[used_index];
        ++used_index;
      } else {
        entry["rejected_because"] = view.rejected_because;
      }
      images.push_back(entry);
    }
    const nlohmann::json out = {{"camera_xml", args.out.string()}, {"width_px", width},
                                {"height_px", height},             {"board", board.ToString()},
                                {"visp", IntrinsicsJson(result.visp)}, {"opencv", IntrinsicsJson(result.opencv)},
                                {"images", images}};
    std::printf("%s\n", out.dump(2).c_str());
    return;
  }
  std::printf("%zu of %zu images used (board %s, %dx%d px)\n", result.used.size(), views.size(),
              board.ToString().c_str(), width, height);
  std::printf("  %-28s %12s %12s\n", "image", "ViSP rms px", "OpenCV rms px");
  std::size_t used_index = 0;
  for (const camera::ViewReport& view : result.views) {
    if (view.used) {
      std::printf("  %-28s %12.4f %12.4f\n", view.name.c_str(), result.visp.view_rms_px[used_index],
                  result.opencv.view_rms_px[used_index]);
      ++used_index;
    } else {
      std::printf("  %-28s rejected: %s\n", view.name.c_str(), view.rejected_because.c_str());
    }
  }
  const camera::Intrinsics& v = result.visp.intrinsics;
  const camera::Intrinsics& o = result.opencv.intrinsics;
  std::printf("  %-10s %14s %14s\n", "", "ViSP", "OpenCV");
  std::printf("  %-10s %14.3f %14.3f\n", "fx px", v.fx_px, o.fx_px);
  std::printf("  %-10s %14.3f %14.3f\n", "fy px", v.fy_px, o.fy_px);
  std::printf("  %-10s %14.3f %14.3f\n", "cx px", v.cx_px, o.cx_px);
  std::printf("  %-10s %14.3f %14.3f\n", "cy px", v.cy_px, o.cy_px);
  std::printf("  %-10s %14.6f %14.6f\n", "kud (k1)", v.kud, o.kud);
  std::printf("  %-10s %14.6f %14s\n", "kdu", v.kdu, "-");
  std::printf("  %-10s %14.4f %14.4f\n", "rms px", result.visp.rms_px, result.opencv.rms_px);
  std::printf("camera XML (ViSP): %s, camera '%s'\n", args.out.string().c_str(), args.camera_name.c_str());
}

// ---- calibrate ground ------------------------------------------------------------------

struct GroundArgs {
  std::string images;
  std::string board;
  std::filesystem::path intrinsics;
  std::string camera_name;
  std::filesystem::path out;
  camera::GroundOptions options;
};

void RunGround(const GroundArgs& args, const GlobalOptions& global) {
  const camera::BoardSpec board = camera::ParseBoardSpec(args.board);
  const camera::Intrinsics intrinsics = camera::ReadVispCameraXml(args.intrinsics, args.camera_name);
  std::string why;
  if (!args.options.Check(&why)) core::ThrowInvalidInput(why);
  const std::vector<std::filesystem::path> files = Glob(args.images);
  int width = 0, height = 0;
  const std::vector<camera::BoardView> views = DetectAll(files, board, &width, &height);
  if (width != intrinsics.width_px || height != intrinsics.height_px) {
    core::ThrowInvalidInput(files.front().string() + ": images are " + std::to_string(width) + "x" +
                            std::to_string(height) + " but " + args.intrinsics.string() + " is for " +
                            std::to_string(intrinsics.width_px) + "x" + std::to_string(intrinsics.height_px));
  }
  const camera::GroundResult result = camera::CalibrateGround(views, board, intrinsics, args.options);
  camera::WriteGroundCalibration(args.out, result.calibration,
                                 "mosaicloc calibrate ground, board " + board.ToString() + ", " +
                                     std::to_string(views.size()) + " images, intrinsics " +
                                     args.intrinsics.filename().string());
  const camera::GroundCalibration& c = result.calibration;
  if (global.json) {
    nlohmann::json images = nlohmann::json::array();
    for (const auto& view : result.views) {
      images.push_back({{"image", view.name},
                        {"residual_rms_mm", view.residual_rms_mm},
                        {"residual_max_mm", view.residual_max_mm},
                        {"scale_error_percent", 100.0 * view.scale_error}});
    }
    const nlohmann::json out = {{"ground", args.out.string()},
                                {"height_mm", c.height_mm()},
                                {"tilt_deg", c.tilt_rad() * 180.0 / M_PI},
                                {"mm_per_px", c.ideal.mm_per_px},
                                {"width_px", c.ideal.width_px},
                                {"height_px", c.ideal.height_px},
                                {"flatness_rms_mm", result.flatness_rms_mm},
                                {"flatness_max_mm", result.flatness_max_mm},
                                {"coverage", result.coverage},
                                {"images", images}};
    std::printf("%s\n", out.dump(2).c_str());
    return;
  }
  std::printf("floor %.3f mm below the camera, optical axis %.3f deg from vertical (%zu images)\n", c.height_mm(),
              c.tilt_rad() * 180.0 / M_PI, views.size());
  std::printf("  %-28s %14s %14s %14s\n", "image", "residual mm", "max mm", "scale error %");
  for (const auto& view : result.views) {
    std::printf("  %-28s %14.4f %14.4f %14.4f\n", view.name.c_str(), view.residual_rms_mm, view.residual_max_mm,
                100.0 * view.scale_error);
  }
  std::printf("  floor flatness over all boards: rms %.4f mm, max %.4f mm\n", result.flatness_rms_mm,
              result.flatness_max_mm);
  std::printf("ideal image %dx%d px at %.4f mm/px, %.1f %% of it inside the raw image: %s\n", c.ideal.width_px,
              c.ideal.height_px, c.ideal.mm_per_px, 100.0 * result.coverage, args.out.string().c_str());
  if (result.coverage < 1.0) {
    std::fprintf(stderr, "mosaicloc: warning: %.1f %% of the ideal image lies outside the raw image (black); "
                 "choose a smaller --width/--height or --mm-per-px\n", 100.0 * (1.0 - result.coverage));
  }
}

// ---- calibrate rectify / verify --------------------------------------------------------

struct RectifyArgs {
  std::string images;
  std::filesystem::path ground;
  std::filesystem::path out_dir;
  std::string board;  // verify only
};

void RunRectify(const RectifyArgs& args, const GlobalOptions& global) {
  const camera::Rectifier rectifier(camera::ReadGroundCalibration(args.ground));
  const std::vector<std::filesystem::path> files = Glob(args.images);
  std::vector<cv::Mat> rectified;
  for (const std::filesystem::path& file : files) {
    cv::Mat ideal;
    if (!rectifier.Rectify(ReadGrey(file), &ideal)) {
      core::ThrowInvalidInput(file.string() + ": not the calibrated raw size " +
                              std::to_string(rectifier.calibration().intrinsics.width_px) + "x" +
                              std::to_string(rectifier.calibration().intrinsics.height_px));
    }
    rectified.push_back(ideal);
  }
  std::filesystem::create_directories(args.out_dir);
  for (std::size_t i = 0; i < files.size(); ++i) {
    WritePng(args.out_dir / files[i].filename().replace_extension(".png"), rectified[i]);
  }
  if (global.json) {
    std::printf("%s\n", nlohmann::json{{"images", files.size()}, {"out", args.out_dir.string()}}.dump(2).c_str());
  } else {
    std::printf("%zu images rectified into %s\n", files.size(), args.out_dir.string().c_str());
  }
}

void RunVerify(const RectifyArgs& args, const GlobalOptions& global) {
  const camera::BoardSpec board = camera::ParseBoardSpec(args.board);
  const camera::Rectifier rectifier(camera::ReadGroundCalibration(args.ground));
  const std::vector<std::filesystem::path> files = Glob(args.images);
  nlohmann::json images = nlohmann::json::array();
  double worst_scale = 0.0;
  if (!global.json) std::printf("  %-28s %14s %14s %14s\n", "image", "scale error %", "residual mm", "max mm");
  for (const std::filesystem::path& file : files) {
    cv::Mat ideal;
    if (!rectifier.Rectify(ReadGrey(file), &ideal)) {
      core::ThrowInvalidInput(file.string() + ": not the calibrated raw size");
    }
    const auto detection = camera::DetectBoard(ideal, board);
    if (!detection) core::ThrowInvalidInput(file.string() + ": board " + board.ToString() + " not found once rectified");
    const camera::IdealBoardMeasurement m = camera::MeasureIdealBoard(*detection, board, rectifier.calibration().ideal);
    worst_scale = std::max(worst_scale, std::abs(m.scale_error));
    images.push_back({{"image", file.filename().string()},
                      {"scale_error_percent", 100.0 * m.scale_error},
                      {"residual_rms_mm", m.residual_rms_mm},
                      {"residual_max_mm", m.residual_max_mm}});
    if (!global.json) {
      std::printf("  %-28s %14.4f %14.4f %14.4f\n", file.filename().string().c_str(), 100.0 * m.scale_error,
                  m.residual_rms_mm, m.residual_max_mm);
    }
  }
  if (global.json) {
    std::printf("%s\n", nlohmann::json{{"images", images}, {"worst_scale_error_percent", 100.0 * worst_scale}}
                            .dump(2)
                            .c_str());
  } else {
    std::printf("rectified images measure the board to within %.4f %% of its printed size\n", 100.0 * worst_scale);
  }
}

// ---- calibrate simulate ----------------------------------------------------------------

struct SimulateArgs {
  std::filesystem::path out;
  std::string board = "chessboard:9x6:20mm";
  std::string floor_board = "chessboard:9x6:10mm";
  int shots = 12;
  std::uint64_t seed = 1;
};

void RunSimulate(const SimulateArgs& args, const GlobalOptions& global) {
  const camera::BoardSpec board = camera::ParseBoardSpec(args.board);
  const camera::BoardSpec floor_board = camera::ParseBoardSpec(args.floor_board);
  const camera::RealCameraOptions truth = sim::CalibrationTruthCamera();
  const std::vector<sim::BoardShot> shots =
      sim::RenderIntrinsicsShots(truth, board, args.shots, 0.42, sim::RawImagingOptions{}, args.seed);
  // The floor board in the four quadrants of the view, so the fitted plane spans the image.
  const camera::RealCamera mounted(truth);
  const std::vector<core::Pose2> placements = {
      {-62.0, -42.0, 0.05}, {-18.0, -42.0, -0.05}, {-62.0, -8.0, 0.0}, {-18.0, -8.0, 0.05}, {-42.0, -30.0, -0.08}};
  const double scale = floor_board.pitch_mm / 10.0;
  // 16 x 16 samples per pixel: with fewer, an edge that runs along the pixel grid (the third
  // placement) moves in steps of a quarter pixel, which no real camera does, and its corners
  // err by 0.1 px: enough to tilt the fitted floor by 10^-4 rad.
  sim::RawImagingOptions floor_imaging;
  floor_imaging.supersampling = 16;
  std::vector<cv::Mat> floor_images;
  for (std::size_t i = 0; i < placements.size(); ++i) {
    const core::Pose2 placement(placements[i].translation_mm() * scale, placements[i].yaw_rad());
    floor_images.push_back(sim::RenderBoardRaw(mounted, floor_board, placement, floor_imaging, args.seed * 1000 + i));
  }
  std::filesystem::create_directories(args.out / "intrinsics");
  std::filesystem::create_directories(args.out / "ground");
  char name[64];
  for (std::size_t i = 0; i < shots.size(); ++i) {
    std::snprintf(name, sizeof(name), "board-%02zu.png", i + 1);
    WritePng(args.out / "intrinsics" / name, shots[i].image);
  }
  for (std::size_t i = 0; i < floor_images.size(); ++i) {
    std::snprintf(name, sizeof(name), "floor-%02zu.png", i + 1);
    WritePng(args.out / "ground" / name, floor_images[i]);
  }
  char text[1024];
  std::snprintf(text, sizeof(text),
                "# The simulated camera the images were made with (camera::RealCamera).\n"
                "fx_px: %.6f\nfy_px: %.6f\ncx_px: %.6f\ncy_px: %.6f\nk1: %.6f\nheight_mm: %.6f\n"
                "tilt_x_rad: %.6f\ntilt_y_rad: %.6f\nboard: %s\nfloor_board: %s\n",
                truth.fx_px, truth.fy_px, truth.cx_px, truth.cy_px, truth.k1, truth.height_mm, truth.tilt_x_rad,
                truth.tilt_y_rad, board.ToString().c_str(), floor_board.ToString().c_str());
  core::WriteFileAtomically(args.out / "truth.yaml", text);
  if (global.json) {
    std::printf("%s\n", nlohmann::json{{"out", args.out.string()},
                                       {"board_images", shots.size()},
                                       {"floor_images", floor_images.size()}}
                            .dump(2)
                            .c_str());
  } else {
    std::printf("%zu board photographs in %s, %zu of the board on the floor in %s; the truth in %s\n",
                shots.size(), (args.out / "intrinsics").string().c_str(), floor_images.size(),
                (args.out / "ground").string().c_str(), (args.out / "truth.yaml").string().c_str());
  }
}


// ---- calibrate vehicle / simulate-drive ------------------------------------------------

struct VehicleArgs {
  std::filesystem::path dataset;
  std::filesystem::path out;
};

std::string Number(double value) {
  char text[40];
  std::snprintf(text, sizeof(text), "%.9g", value);
  return text;
}

void RunVehicle(const VehicleArgs& args, const GlobalOptions& global) {
  const dataset::DatasetReader reader(args.dataset);
  const dataset::DatasetInfo& info = reader.info();
  std::vector<dataset::EncoderSample> encoders;
  {
    auto stream = reader.Encoders();
    while (auto sample = stream.Next()) encoders.push_back(*sample);
  }
  if (encoders.size() < 2) core::ThrowInvalidInput(args.dataset.string() + ": the drive has no encoder samples");
  // Unwrapped tick counts (the PLC's int32 counters may wrap), interpolated at a time.
  std::vector<double> left(encoders.size()), right(encoders.size());
  for (std::size_t i = 1; i < encoders.size(); ++i) {
    const auto delta = [](std::int32_t a, std::int32_t b) {
      return static_cast<double>(static_cast<std::int32_t>(static_cast<std::uint32_t>(b) - static_cast<std::uint32_t>(a)));
    };
    left[i] = left[i - 1] + delta(encoders[i - 1].left_ticks, encoders[i].left_ticks);
    right[i] = right[i - 1] + delta(encoders[i - 1].right_ticks, encoders[i].right_ticks);
  }
  const auto ticks_at = [&](core::Timestamp t) -> std::optional<Eigen::Vector2d> {
    const auto after = std::lower_bound(encoders.begin(), encoders.end(), t,
                                        [](const dataset::EncoderSample& s, core::Timestamp x) { return s.time < x; });
    if (after == encoders.end()) return std::nullopt;
    const std::size_t j = static_cast<std::size_t>(after - encoders.begin());
    if (after->time == t) return Eigen::Vector2d(left[j], right[j]);
    if (j == 0) return std::nullopt;
    const double a = static_cast<double>((t - encoders[j - 1].time).count()) /
                     static_cast<double>((encoders[j].time - encoders[j - 1].time).count());
    return Eigen::Vector2d(left[j - 1] + a * (left[j] - left[j - 1]), right[j - 1] + a * (right[j] - right[j - 1]));
  };
  const double rad_per_tick = 2.0 * M_PI / static_cast<double>(info.vehicle.ticks_per_revolution);

  camera::IdealCameraOptions camera_options;
  camera_options.width_px = info.camera.width_px;
  camera_options.height_px = info.camera.height_px;
  camera_options.mm_per_px = info.camera.mm_per_px;
  const camera::IdealCamera camera(camera_options);
  // The tracker's matcher, set for accuracy rather than speed: the whole frame cut into
  // templates (every part of the overlap used), and a wider low-pass, which keeps the
  // sub-pixel estimate from locking onto the pixel grid (a bias that repeats with the same
  // fractional shift and would not average out).
  tracking::TrackerOptions tracker_options;
  tracker_options.templates.mode = tracking::TemplateMode::kTiled;
  tracker_options.templates.tile_cols = 6;
  tracker_options.templates.tile_rows = 4;
  tracker_options.refine.prefilter_sigma_px = 2.0;
  const tracking::Tracker tracker(camera, tracker_options);
  camera::VehicleCalibrationOptions options;
  options.initial_wheels = {info.vehicle.left_wheel_radius_mm, info.vehicle.right_wheel_radius_mm,
                            info.vehicle.track_width_mm};
  options.initial_vehicle_from_camera = info.camera.vehicle_from_camera;

  // The lens's vignetting stays on the pixels while the floor moves: estimated from the drive
  // itself and divided out before registering.
  cv::Mat gain;
  {
    camera::FlatFieldEstimator flat;
    auto all = reader.Frames();
    while (auto frame = all.Next()) flat.Add(frame->image);
    gain = flat.Gain();
  }

  // Each frame is registered to the one before it (the chain that predicts the others) and
  // to up to kBaselines earlier frames it still overlaps: the longer the baseline, the
  // smaller a registration error is against the motion.
  constexpr int kBaselines = 12;
  constexpr double kMinOverlap = 0.2;
  struct Kept {
    cv::Mat image;
    camera::WheelTurn turn;         // since the previous frame
    core::Pose2 chain_from_camera;  // from the consecutive registrations
  };
  std::deque<Kept> window;
  std::vector<camera::DriveStep> steps;
  int failed = 0, frames = 0, consecutive = 0;
  Eigen::Vector2d previous_ticks = Eigen::Vector2d::Zero();
  std::optional<core::Pose2> last_motion;
  auto stream = reader.Frames();
  ProgressBar progress("calibrate vehicle", global.quiet);
  const double width_mm = camera.width_px() * camera.mm_per_px(), height_mm = camera.height_px() * camera.mm_per_px();
  const auto overlap = [&](const core::Pose2& motion) {
    // Share of the frame both images show, from the displacement of the corners.
    double shift_x = 0.0, shift_y = 0.0;
    for (const double x : {-0.5 * width_mm, 0.5 * width_mm}) {
      for (const double y : {-0.5 * height_mm, 0.5 * height_mm}) {
        const Eigen::Vector2d moved = motion * Eigen::Vector2d(x, y);
        shift_x = std::max(shift_x, std::abs(moved.x() - x));
        shift_y = std::max(shift_y, std::abs(moved.y() - y));
      }
    }
    return std::max(0.0, 1.0 - shift_x / width_mm) * std::max(0.0, 1.0 - shift_y / height_mm);
  };
  while (auto frame = stream.Next()) {
    ++frames;
    const auto ticks = ticks_at(frame->time);
    if (!ticks) continue;
    Kept current{camera::DivideByGain(frame->image, gain), {}, core::Pose2()};
    if (!window.empty()) {
      camera::DriveStep step;
      step.left_wheel_rad = ((*ticks)(0) - previous_ticks(0)) * rad_per_tick;
      step.right_wheel_rad = ((*ticks)(1) - previous_ticks(1)) * rad_per_tick;
      current.turn = {step.left_wheel_rad, step.right_wheel_rad};
      // The prior: the last registered motion (the drive is smooth), or the nominal odometry.
      core::Pose2 prior = last_motion.value_or(core::Pose2());
      if (!last_motion) {
        const double d = 0.5 * (options.initial_wheels.left_wheel_radius_mm * step.left_wheel_rad +
                                options.initial_wheels.right_wheel_radius_mm * step.right_wheel_rad);
        const double theta = (options.initial_wheels.right_wheel_radius_mm * step.right_wheel_rad -
                              options.initial_wheels.left_wheel_radius_mm * step.left_wheel_rad) /
                             options.initial_wheels.track_width_mm;
        prior = options.initial_vehicle_from_camera.Inverse() * core::Pose2(d, 0.0, theta) *
                options.initial_vehicle_from_camera;
      }
      const double sigma_mm = 3.0, sigma_rad = 0.01;
      const Eigen::Matrix3d covariance =
          Eigen::Vector3d(sigma_mm * sigma_mm, sigma_mm * sigma_mm, sigma_rad * sigma_rad).asDiagonal();
      const tracking::TrackResult r =
          tracking::RegisterFrames(tracker, window.back().image, current.image, prior, covariance);
      if (r.ok()) {
        step.previous_from_current_camera = r.world_from_camera;
        last_motion = r.world_from_camera;
        steps.push_back(step);
        ++consecutive;
        current.chain_from_camera = window.back().chain_from_camera * r.world_from_camera;
        // The chain predicts the longer baselines to a fraction of a pixel.
        const Eigen::Matrix3d chained = Eigen::Vector3d(0.25, 0.25, 1e-6).asDiagonal();
        while (window.size() > 1 &&
               overlap(window.front().chain_from_camera.Inverse() * current.chain_from_camera) < kMinOverlap) {
          window.pop_front();
        }
        // Up to kBaselines of the earlier frames, evenly spread, the oldest first.
        const int earlier = static_cast<int>(window.size()) - 1;
        const int used = std::min(earlier, kBaselines);
        for (int n = 0; n < used; ++n) {
          const int index = static_cast<int>(std::lround(static_cast<double>(n) * earlier / used));
          const Kept& from = window[static_cast<std::size_t>(index)];
          const tracking::TrackResult far = tracking::RegisterFrames(
              tracker, from.image, current.image, from.chain_from_camera.Inverse() * current.chain_from_camera, chained);
          if (!far.ok()) continue;
          camera::DriveStep long_step;
          long_step.previous_from_current_camera = far.world_from_camera;
          for (std::size_t i = static_cast<std::size_t>(index) + 1; i < window.size(); ++i) {
            long_step.arcs.push_back(window[i].turn);
          }
          long_step.arcs.push_back(current.turn);
          steps.push_back(long_step);
        }
      } else {
        ++failed;
        last_motion.reset();
        window.clear();
        core::Log().debug("frame {}: not registered to the previous one: {}", frame->time.nanoseconds(), r.reason);
      }
    }
    window.push_back(std::move(current));
    previous_ticks = *ticks;
  }
  // The pairs of a frame share its noise: the uncertainty counts frames, not pairs.
  options.independent_steps = consecutive;
  progress.Finish();
  const camera::VehicleCalibrationResult result = camera::CalibrateVehicle(steps, options);
  if (!result.converged) {
    core::ThrowInvalidInput(args.dataset.string() + ": vehicle calibration failed: " + result.message + " (" +
                            std::to_string(consecutive) + " consecutive frame pairs registered, " + std::to_string(failed) +
                            " not)");
  }
  const core::Pose2& x = result.vehicle_from_camera;
  const camera::WheelGeometry& w = result.wheels;
  const auto& sigma = result.sigma;
  if (!args.out.empty()) {
    std::string out;
    out += "# mosaicloc vehicle calibration (mosaicloc calibrate vehicle --dataset " + args.dataset.string() + ")\n";
    out += "# from " + std::to_string(steps.size()) + " registered frame pairs (" + std::to_string(consecutive) +
           " consecutive); sigma_* are one-sigma uncertainties.\n";
    out += "# Copy the values into run.yaml (camera.vehicle_from_camera, vehicle.*).\n";
    out += "format_version: 1\n";
    out += "vehicle_from_camera: {x_mm: " + Number(x.x_mm()) + ", y_mm: " + Number(x.y_mm()) +
           ", yaw_rad: " + Number(x.yaw_rad()) + "}\n";
    out += "vehicle_from_camera_sigma: {x_mm: " + Number(sigma(0)) + ", y_mm: " + Number(sigma(1)) +
           ", yaw_rad: " + Number(sigma(2)) + "}\n";
    out += "left_wheel_radius_mm: " + Number(w.left_wheel_radius_mm) + "\n";
    out += "right_wheel_radius_mm: " + Number(w.right_wheel_radius_mm) + "\n";
    out += "track_width_mm: " + Number(w.track_width_mm) + "\n";
    out += "wheel_sigma: {left_wheel_radius_mm: " + Number(sigma(3)) + ", right_wheel_radius_mm: " +
           Number(sigma(4)) + ", track_width_mm: " + Number(sigma(5)) + "}\n";
    core::WriteFileAtomically(args.out, out);
  }
  // A simulated drive carries its truth: show the errors too.
  std::optional<std::array<double, 6>> truth;
  const auto& p = info.provenance;
  if (p.count("truth_vehicle_from_camera") && p.count("truth_left_wheel_radius_mm") &&
      p.count("truth_right_wheel_radius_mm") && p.count("truth_track_width_mm")) {
    std::array<double, 6> t{};
    if (std::sscanf(p.at("truth_vehicle_from_camera").c_str(), "%lf %lf %lf", &t[0], &t[1], &t[2]) == 3) {
      t[3] = std::stod(p.at("truth_left_wheel_radius_mm"));
      t[4] = std::stod(p.at("truth_right_wheel_radius_mm"));
      t[5] = std::stod(p.at("truth_track_width_mm"));
      truth = t;
    }
  }
  const std::array<double, 6> value{x.x_mm(), x.y_mm(), x.yaw_rad(), w.left_wheel_radius_mm, w.right_wheel_radius_mm,
                                    w.track_width_mm};
  const char* names[6] = {"camera x mm", "camera y mm", "camera yaw deg", "left radius mm", "right radius mm",
                          "track width mm"};
  const double unit[6] = {1.0, 1.0, 180.0 / M_PI, 1.0, 1.0, 1.0};
  if (global.json) {
    nlohmann::json out = {{"frames", frames}, {"steps", steps.size()}, {"consecutive_steps", consecutive},
                          {"not_registered", failed},
                          {"iterations", result.iterations},
                          {"rms_translation_mm", result.rms_translation_mm},
                          {"rms_rotation_deg", result.rms_rotation_rad * 180.0 / M_PI}};
    const char* keys[6] = {"x_mm", "y_mm", "yaw_deg", "left_wheel_radius_mm", "right_wheel_radius_mm",
                           "track_width_mm"};
    for (int i = 0; i < 6; ++i) {
      out[keys[i]] = {{"value", value[i] * unit[i]}, {"sigma", sigma(i) * unit[i]}};
      if (truth) {
        out[keys[i]]["truth"] = (*truth)[i] * unit[i];
        out[keys[i]]["error"] = (value[i] - (*truth)[i]) * unit[i];
      }
    }
    if (!args.out.empty()) out["out"] = args.out.string();
    std::printf("%s\n", out.dump(2).c_str());
    return;
  }
  std::printf("%d of %d consecutive frame pairs registered, %zu pairs in all; residuals %.4f mm, %.5f deg per pair\n",
              consecutive, frames - 1, steps.size(), result.rms_translation_mm, result.rms_rotation_rad * 180.0 / M_PI);
  std::printf("  %-16s %14s %12s", "", "calibrated", "sigma");
  if (truth) std::printf(" %14s %12s", "truth", "error");
  std::printf("\n");
  for (int i = 0; i < 6; ++i) {
    std::printf("  %-16s %14.4f %12.4f", names[i], value[i] * unit[i], sigma(i) * unit[i]);
    if (truth) std::printf(" %14.4f %12.4f", (*truth)[i] * unit[i], (value[i] - (*truth)[i]) * unit[i]);
    std::printf("\n");
  }
  if (!args.out.empty()) std::printf("vehicle calibration: %s\n", args.out.string().c_str());
}

struct DriveArgs {
  std::filesystem::path out;
  std::uint64_t seed = 1;
  double mounting_yaw_deg = sim::CalibrationDriveOptions{}.vehicle_from_camera.yaw_rad() * 180.0 / M_PI;
  double ramp_frames = 0.0;
  bool overwrite = false;
};

void RunSimulateDrive(const DriveArgs& args, const GlobalOptions& global) {
  sim::CalibrationDriveOptions options;
  options.seed = args.seed;
  options.floor.seed = args.seed;
  options.vehicle_from_camera = core::Pose2(options.vehicle_from_camera.x_mm(), options.vehicle_from_camera.y_mm(),
                                            args.mounting_yaw_deg * M_PI / 180.0);
  options.ramp_frames = args.ramp_frames;
  const sim::CalibrationDriveSummary summary = sim::WriteCalibrationDrive(options, args.out, args.overwrite);
  if (global.json) {
    std::printf("%s\n", nlohmann::json{{"dataset", args.out.string()}, {"frames", summary.frames}}.dump(2).c_str());
  } else {
    std::printf("calibration drive %s: %d frames, a %.0f mm straight run then a %.0f deg turn in place\n",
                args.out.string().c_str(), summary.frames, options.straight_mm, options.turn_rad * 180.0 / M_PI);
  }
}


// ---- calibrate simulate-raw / rectify-dataset ------------------------------------------

// A simulated calibration drive records nominal values in dataset.yaml and its truth in
// the provenance; the raw images must be made at the true mounting.
core::Pose2 TrueMounting(const dataset::DatasetInfo& info) {
  const auto truth = info.provenance.find("truth_vehicle_from_camera");
  double x = 0.0, y = 0.0, yaw = 0.0;
  if (truth != info.provenance.end() && std::sscanf(truth->second.c_str(), "%lf %lf %lf", &x, &y, &yaw) == 3) {
    return core::Pose2(x, y, yaw);
  }
  return info.camera.vehicle_from_camera;
}

// vehicle_from_camera from a vehicle calibration file (calibrate vehicle --out).
core::Pose2 ReadVehicleMounting(const std::filesystem::path& file) {
  const YAML::Node node = core::LoadYamlFile(file);
  core::YamlProblems problems;
  core::YamlMap root = core::YamlMap::Root(node, file.string(), &problems);
  int version = 0;
  root.Required("format_version", &version, core::IntegerInRange(1, 1));
  double x = 0.0, y = 0.0, yaw = 0.0, ignored = 0.0;
  core::YamlMap mounting = root.RequiredMap("vehicle_from_camera");
  mounting.Required("x_mm", &x);
  mounting.Required("y_mm", &y);
  mounting.Required("yaw_rad", &yaw, core::InRange(-M_PI, M_PI));
  mounting.Finish();
  core::YamlMap sigma = root.RequiredMap("vehicle_from_camera_sigma");
  for (const char* key : {"x_mm", "y_mm", "yaw_rad"}) sigma.Required(key, &ignored);
  sigma.Finish();
  for (const char* key : {"left_wheel_radius_mm", "right_wheel_radius_mm", "track_width_mm"}) {
    root.Required(key, &ignored, core::Positive());
  }
  core::YamlMap wheel_sigma = root.RequiredMap("wheel_sigma");
  for (const char* key : {"left_wheel_radius_mm", "right_wheel_radius_mm", "track_width_mm"}) {
    wheel_sigma.Required(key, &ignored);
  }
  wheel_sigma.Finish();
  root.Finish();
  problems.ThrowIfAny();
  return core::Pose2(x, y, yaw);
}

struct RawArgs {
  std::filesystem::path dataset;
  std::filesystem::path config;
  std::filesystem::path out;
  std::filesystem::path ground;   // rectify-dataset
  std::filesystem::path vehicle;  // rectify-dataset: calibrated vehicle_from_camera
  bool overwrite = false;
};

dataset::DatasetWriter CopyHeader(const dataset::DatasetReader& reader, const dataset::CameraInfo& camera,
                                  const std::string& note, const std::filesystem::path& out, bool overwrite) {
  dataset::DatasetInfo info = reader.info();
  info.camera.width_px = camera.width_px;
  info.camera.height_px = camera.height_px;
  info.camera.mm_per_px = camera.mm_per_px;
  info.camera.vehicle_from_camera = camera.vehicle_from_camera;
  info.provenance["calibration"] = note;
  return dataset::DatasetWriter(out, info, overwrite);
}

void CopyEncodersAndTruth(const dataset::DatasetReader& reader, dataset::DatasetWriter* writer) {
  auto encoders = reader.Encoders();
  while (auto sample = encoders.Next()) writer->AddEncoderSample(*sample);
  if (reader.HasGroundTruth()) writer->SetGroundTruth(reader.GroundTruth());
}

// The same drive seen through the simulated real camera: every frame rendered raw (distorted,
// tilted) at its true camera pose, over the floor of the simulator configuration.
void RunSimulateRaw(const RawArgs& args, const GlobalOptions& global) {
  const dataset::DatasetReader reader(args.dataset);
  if (!reader.HasGroundTruth()) core::ThrowInvalidInput(args.dataset.string() + ": needs ground truth");
  const sim::SimulatorOptions options = args.config.empty() ? sim::SimulatorOptions{} : LoadSimulatorConfig(args.config);
  const auto floor = sim::MakeFloor(options.floor);
  const dataset::Trajectory truth = reader.GroundTruth();
  const core::Pose2 vehicle_from_camera = TrueMounting(reader.info());
  const camera::RealCamera raw_camera(sim::CalibrationTruthCamera());
  sim::RawImagingOptions imaging;
  imaging.noise_std_dn = options.imaging.noise_std_dn;
  imaging.black_dn = 0.0;
  imaging.white_dn = 255.0;
  dataset::CameraInfo raw_info = reader.info().camera;
  raw_info.width_px = raw_camera.options().width_px;
  raw_info.height_px = raw_camera.options().height_px;
  dataset::DatasetWriter writer =
      CopyHeader(reader, raw_info, "raw images of the simulated real camera (calibrate simulate-raw)", args.out,
                 args.overwrite);
  std::int64_t total = 0;
  for (auto listing = reader.Frames(); listing.Next(/*decode=*/false);) ++total;
  ProgressBar progress("simulate raw", global.quiet);
  auto frames = reader.Frames();
  std::int64_t count = 0;
  while (auto frame = frames.Next(/*decode=*/false)) {
    const auto world_from_vehicle = dataset::PoseAt(truth, frame->time, std::chrono::milliseconds(100));
    if (!world_from_vehicle) core::ThrowInvalidInput(frame->path.string() + ": no ground truth at its time");
    writer.AddFrame(frame->time, sim::RenderFloorRaw(raw_camera, *floor, *world_from_vehicle * vehicle_from_camera,
                                                     imaging, options.seed * 7919 + static_cast<std::uint64_t>(count)));
    progress.Update(static_cast<double>(++count) / static_cast<double>(std::max<std::int64_t>(1, total)));
  }
  CopyEncodersAndTruth(reader, &writer);
  writer.Commit();
  progress.Finish();
  if (global.json) {
    std::printf("%s\n", nlohmann::json{{"dataset", args.out.string()}, {"frames", count}}.dump(2).c_str());
  } else {
    std::printf("%lld raw frames in %s\n", static_cast<long long>(count), args.out.string().c_str());
  }
}

// A recording of raw images made ideal, as a camera source does it live.
void RunRectifyDataset(const RawArgs& args, const GlobalOptions& global) {
  const camera::Rectifier rectifier(camera::ReadGroundCalibration(args.ground));
  const dataset::DatasetReader reader(args.dataset);
  const camera::IdealCameraOptions& ideal = rectifier.calibration().ideal;
  dataset::CameraInfo ideal_info = reader.info().camera;
  ideal_info.width_px = ideal.width_px;
  ideal_info.height_px = ideal.height_px;
  ideal_info.mm_per_px = ideal.mm_per_px;
  if (!args.vehicle.empty()) ideal_info.vehicle_from_camera = ReadVehicleMounting(args.vehicle);
  dataset::DatasetWriter writer = CopyHeader(
      reader, ideal_info, "rectified with " + args.ground.filename().string() + " (calibrate rectify-dataset)",
      args.out, args.overwrite);
  auto frames = reader.Frames();
  std::int64_t count = 0;
  while (auto frame = frames.Next()) {
    cv::Mat rectified;
    if (!rectifier.Rectify(frame->image, &rectified)) {
      core::ThrowInvalidInput(frame->path.string() + ": not the calibrated raw size");
    }
    writer.AddFrame(frame->time, rectified);
    ++count;
  }
  CopyEncodersAndTruth(reader, &writer);
  writer.Commit();
  if (global.json) {
    std::printf("%s\n", nlohmann::json{{"dataset", args.out.string()}, {"frames", count}}.dump(2).c_str());
  } else {
    std::printf("%lld frames rectified into %s (%dx%d at %.4f mm/px)\n", static_cast<long long>(count),
                args.out.string().c_str(), ideal.width_px, ideal.height_px, ideal.mm_per_px);
  }
}

}  // namespace

Action AddCalibrateCommand(CLI::App& app, const GlobalOptions& global) {
  CLI::App* command = app.add_subcommand("calibrate", "Calibrate a camera: intrinsics, ground plane, rectification");
  command->require_subcommand(1);
  const std::string board_help = "chessboard:COLSxROWS:PITCHmm (inner corners), circles:... or acircles:...";

  auto board_args = std::make_shared<BoardArgs>();
  CLI::App* board = command->add_subcommand("board", "Write a printable calibration board (PNG)");
  board->add_option("--board", board_args->board, board_help)->capture_default_str();
  board->add_option("--out", board_args->out, "PNG to write")->required();
  board->add_option("--px-per-mm", board_args->px_per_mm, "Print resolution (default 300 dpi)")
      ->check(CLI::Range(0.5, 50.0));

  auto intrinsics_args = std::make_shared<IntrinsicsArgs>();
  CLI::App* intrinsics = command->add_subcommand("intrinsics", "Intrinsics and distortion from board photographs");
  intrinsics->add_option("--images", intrinsics_args->images, "Photographs of the board, a quoted pattern like 'cal/*.png'")
      ->required();
  intrinsics->add_option("--board", intrinsics_args->board, board_help)->required();
  intrinsics->add_option("--out", intrinsics_args->out, "ViSP camera XML to write (replaced atomically)")->required();
  intrinsics->add_option("--camera-name", intrinsics_args->camera_name, "Camera name in the XML")->capture_default_str();

  auto ground_args = std::make_shared<GroundArgs>();
  CLI::App* ground = command->add_subcommand("ground", "Ground plane and rectification from a board lying on the floor");
  ground->add_option("--images", ground_args->images, "Raw images of the board on the floor (quoted pattern)")->required();
  ground->add_option("--board", ground_args->board, board_help)->required();
  ground->add_option("--intrinsics", ground_args->intrinsics, "ViSP camera XML (calibrate intrinsics)")->required();
  ground->add_option("--camera-name", ground_args->camera_name, "Camera in the XML (default: the first)");
  ground->add_option("--mm-per-px", ground_args->options.mm_per_px, "Ideal image resolution, mm per pixel")
      ->capture_default_str()
      ->check(CLI::Range(0.001, 100.0));
  ground->add_option("--width", ground_args->options.width_px, "Ideal image width, px (default: the raw width)")
      ->check(CLI::Range(8, 16384));
  ground->add_option("--height", ground_args->options.height_px, "Ideal image height, px (default: the raw height)")
      ->check(CLI::Range(8, 16384));
  ground->add_option("--out", ground_args->out, "Ground calibration YAML to write (calib/README.md)")->required();

  auto rectify_args = std::make_shared<RectifyArgs>();
  CLI::App* rectify = command->add_subcommand("rectify", "Turn raw images into ideal ones");
  rectify->add_option("--ground", rectify_args->ground, "Ground calibration YAML")->required();
  rectify->add_option("--images", rectify_args->images, "Raw images (quoted pattern)")->required();
  rectify->add_option("--out-dir", rectify_args->out_dir, "Folder for the ideal PNGs")->required();

  auto verify_args = std::make_shared<RectifyArgs>();
  CLI::App* verify = command->add_subcommand("verify", "Rectify photographs of a board on the floor and measure it");
  verify->add_option("--ground", verify_args->ground, "Ground calibration YAML")->required();
  verify->add_option("--images", verify_args->images, "Raw images of the board on the floor (quoted pattern)")->required();
  verify->add_option("--board", verify_args->board, board_help)->required();

  auto simulate_args = std::make_shared<SimulateArgs>();
  CLI::App* simulate = command->add_subcommand(
      "simulate", "Photographs of boards through a simulated real camera (known truth), for trying the steps");
  simulate->add_option("--out", simulate_args->out, "Folder to write")->required();
  simulate->add_option("--board", simulate_args->board, "Hand-held board")->capture_default_str();
  simulate->add_option("--floor-board", simulate_args->floor_board, "Board laid on the floor")->capture_default_str();
  simulate->add_option("--shots", simulate_args->shots, "Photographs of the hand-held board")
      ->capture_default_str()
      ->check(CLI::Range(3, 100));
  simulate->add_option("--seed", simulate_args->seed, "Noise and pose seed")->capture_default_str();

  auto vehicle_args = std::make_shared<VehicleArgs>();
  CLI::App* vehicle = command->add_subcommand(
      "vehicle", "The camera's place on the vehicle and the wheel geometry from a calibration drive");
  vehicle->add_option("--dataset", vehicle_args->dataset,
                      "Recorded drive (ideal images and encoders): a straight run, then a turn in place")
      ->required();
  vehicle->add_option("--out", vehicle_args->out, "Vehicle calibration YAML to write");

  auto drive_args = std::make_shared<DriveArgs>();
  CLI::App* drive = command->add_subcommand("simulate-drive", "A simulated calibration drive with known truth");
  drive->add_option("--out", drive_args->out, "Dataset directory to write")->required();
  drive->add_option("--seed", drive_args->seed, "Floor and noise seed")->capture_default_str();
  drive->add_option("--mounting-yaw-deg", drive_args->mounting_yaw_deg, "The camera's true yaw on the vehicle, deg")
      ->capture_default_str()
      ->check(CLI::Range(-180.0, 180.0));
  drive->add_option("--ramp-frames", drive_args->ramp_frames,
                    "Frames over which the vehicle speeds up from rest and slows down again (0: constant speed)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1000.0));
  drive->add_flag("--overwrite", drive_args->overwrite, "Replace an existing dataset directory");

  auto raw_args = std::make_shared<RawArgs>();
  CLI::App* raw = command->add_subcommand(
      "simulate-raw", "A simulated dataset seen through the simulated real camera (distorted, tilted raw images)");
  raw->add_option("--dataset", raw_args->dataset, "Simulated dataset with ground truth")->required();
  raw->add_option("--config", raw_args->config, "The simulator configuration it was made with (its floor)");
  raw->add_option("--out", raw_args->out, "Dataset directory to write")->required();
  raw->add_flag("--overwrite", raw_args->overwrite, "Replace an existing dataset directory");

  auto rectify_dataset_args = std::make_shared<RawArgs>();
  CLI::App* rectify_dataset =
      command->add_subcommand("rectify-dataset", "Make a recording of raw images ideal with a ground calibration");
  rectify_dataset->add_option("--dataset", rectify_dataset_args->dataset, "Recording of raw images")->required();
  rectify_dataset->add_option("--ground", rectify_dataset_args->ground, "Ground calibration YAML")->required();
  rectify_dataset->add_option("--out", rectify_dataset_args->out, "Dataset directory to write")->required();
  rectify_dataset->add_option("--vehicle", rectify_dataset_args->vehicle,
                              "Vehicle calibration YAML (calibrate vehicle): its vehicle_from_camera goes in the dataset");
  rectify_dataset->add_flag("--overwrite", rectify_dataset_args->overwrite, "Replace an existing dataset directory");

  return [=, &global] {
    if (raw->parsed()) RunSimulateRaw(*raw_args, global);
    if (rectify_dataset->parsed()) RunRectifyDataset(*rectify_dataset_args, global);
    if (vehicle->parsed()) RunVehicle(*vehicle_args, global);
    if (drive->parsed()) RunSimulateDrive(*drive_args, global);
    if (board->parsed()) RunBoard(*board_args, global);
    if (intrinsics->parsed()) RunIntrinsics(*intrinsics_args, global);
    if (ground->parsed()) RunGround(*ground_args, global);
    if (rectify->parsed()) RunRectify(*rectify_args, global);
    if (verify->parsed()) RunVerify(*verify_args, global);
    if (simulate->parsed()) RunSimulate(*simulate_args, global);
  };
}

}  // namespace mosaicloc::app
