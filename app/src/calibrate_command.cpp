// mosaicloc calibrate: the installation steps that make a vehicle's camera ideal
// (tutorials/calibration): print a board, calibrate the intrinsics, the ground plane and the
// camera's place on the vehicle, rectify, verify.
#include <cstdio>
#include <filesystem>
#include <map>
#include <numbers>
#include <string>

#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "mosaicloc/calibration/board_images.hpp"
#include "mosaicloc/calibration/ground.hpp"
#include "mosaicloc/camera/board.hpp"
#include "mosaicloc/runtime/calibration_jobs.hpp"
#include "mosaicloc/sim/calibration_drive.hpp"
#include "mosaicloc/sim/raw_recordings.hpp"
#include "progress.hpp"
#include "report.hpp"

namespace mosaicloc::app {
namespace {

constexpr double kDegPerRad = 180.0 / std::numbers::pi;

// ---- calibrate board -------------------------------------------------------------------

struct BoardArgs {
  std::string board = "chessboard:9x6:25mm";
  std::filesystem::path out;
  double px_per_mm = 300.0 / 25.4;
};

void RunBoard(const BoardArgs& args, const GlobalOptions& global) {
  const runtime::BoardPrint print = runtime::WriteBoardImage(args.board, args.px_per_mm, args.out);
  const double width_mm = print.width_px / args.px_per_mm, height_mm = print.height_px / args.px_per_mm;
  if (global.json) {
    PrintJson({{"board", print.board.ToString()}, {"png", args.out.string()}, {"width_mm", width_mm},
               {"height_mm", height_mm}});
  } else {
    std::printf("board %s: %s, %dx%d px, print at %.1f x %.1f mm (%.0f dpi) and check one square with a ruler\n",
                print.board.ToString().c_str(), args.out.string().c_str(), print.width_px, print.height_px, width_mm,
                height_mm, args.px_per_mm * 25.4);
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
  const calibration::ImagesIntrinsics calibrated =
      calibration::CalibrateIntrinsicsFromImages(args.images, board, args.out, args.camera_name);
  if (global.json) {
    PrintJson(runtime::IntrinsicsJson(calibrated, board, args.out));
  } else {
    std::fputs(runtime::IntrinsicsText(calibrated, board, args.out, args.camera_name).c_str(), stdout);
  }
}

// ---- calibrate ground ------------------------------------------------------------------

struct GroundArgs {
  std::string images;
  std::string board;
  std::filesystem::path intrinsics;
  std::string camera_name;
  std::filesystem::path out;
  calibration::GroundOptions options;
};

void RunGround(const GroundArgs& args, const GlobalOptions& global) {
  const camera::BoardSpec board = camera::ParseBoardSpec(args.board);
  const calibration::GroundResult result =
      calibration::CalibrateGroundFromImages(args.images, board, args.intrinsics, args.camera_name, args.options, args.out);
  if (global.json) {
    PrintJson(runtime::GroundJson(result, args.out));
    return;
  }
  std::fputs(runtime::GroundText(result, args.out).c_str(), stdout);
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
  const std::size_t images = runtime::RectifyImageFiles(args.ground, args.images, args.out_dir);
  if (global.json) {
    PrintJson(nlohmann::json{{"images", images}, {"out", args.out_dir.string()}});
  } else {
    std::printf("%zu images rectified into %s\n", images, args.out_dir.string().c_str());
  }
}

void RunVerify(const RectifyArgs& args, const GlobalOptions& global) {
  const calibration::RectificationCheck check =
      calibration::VerifyRectification(args.images, args.ground, camera::ParseBoardSpec(args.board));
  if (global.json) {
    PrintJson(runtime::RectificationCheckJson(check));
  } else {
    std::fputs(runtime::RectificationCheckText(check).c_str(), stdout);
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
  sim::CalibrationPhotographsOptions options;
  options.board = camera::ParseBoardSpec(args.board);
  options.floor_board = camera::ParseBoardSpec(args.floor_board);
  options.shots = args.shots;
  options.seed = args.seed;
  const sim::CalibrationPhotographs written = sim::WriteCalibrationPhotographs(options, args.out);
  if (global.json) {
    PrintJson({{"out", args.out.string()}, {"board_images", written.board_images},
               {"floor_images", written.floor_images}});
  } else {
    std::printf("%d board photographs in %s, %d of the board on the floor in %s; the truth in %s\n",
                written.board_images, (args.out / "intrinsics").string().c_str(), written.floor_images,
                (args.out / "ground").string().c_str(), (args.out / "truth.yaml").string().c_str());
  }
}


// ---- calibrate vehicle / simulate-drive ------------------------------------------------

struct VehicleArgs {
  std::filesystem::path dataset;
  std::filesystem::path out;
};

void RunVehicle(const VehicleArgs& args, const GlobalOptions& global) {
  ProgressBar progress("calibrate vehicle", global.quiet);
  const calibration::VehicleDriveResult drive = runtime::CalibrateVehicle(args.dataset, args.out, progress.Callback());
  progress.Finish();
  if (global.json) {
    PrintJson(runtime::VehicleCalibrationJson(drive, args.out));
  } else {
    std::fputs(runtime::VehicleCalibrationText(drive, args.out).c_str(), stdout);
  }
}

void RunSimulateDrive(const runtime::CalibrationDriveJob& args, const GlobalOptions& global) {
  const runtime::SimulatedCalibrationDrive drive = runtime::SimulateCalibrationDrive(args);
  const sim::CalibrationDriveOptions& options = drive.options;
  const sim::CalibrationDriveSummary& summary = drive.summary;
  if (global.json) {
    PrintJson(nlohmann::json{{"dataset", args.out.string()}, {"frames", summary.frames}});
  } else {
    std::printf("calibration drive %s (%s): %d frames, a %.0f mm straight run then a %.0f deg turn in place%s\n",
                args.out.string().c_str(), core::ToString(args.kind), summary.frames, options.straight_mm,
                options.turn_rad * kDegPerRad,
                args.kind == core::DriveKind::kTricycle ? ", the steered wheel across" : "");
  }
}


// ---- calibrate simulate-raw / rectify-dataset ------------------------------------------

struct RawArgs {
  std::filesystem::path dataset;
  std::filesystem::path config;
  std::filesystem::path out;
  std::filesystem::path ground;   // rectify-dataset
  std::filesystem::path vehicle;  // rectify-dataset: calibrated vehicle_from_camera
  bool overwrite = false;
};

// "N frames <what> OUT<detail>", or the JSON of it.
void PrintDataset(const GlobalOptions& global, const std::filesystem::path& out, std::int64_t frames,
                  const char* what, const std::string& detail = "") {
  if (global.json) {
    PrintJson(nlohmann::json{{"dataset", out.string()}, {"frames", frames}});
  } else {
    std::printf("%lld %s %s%s\n", static_cast<long long>(frames), what, out.string().c_str(), detail.c_str());
  }
}

void RunSimulateRaw(const RawArgs& args, const GlobalOptions& global) {
  ProgressBar progress("simulate raw", global.quiet, "no recording was written");
  const std::int64_t frames =
      runtime::SimulateRawRecording(args.dataset, args.config, args.out, args.overwrite, progress.Callback());
  progress.Finish();
  PrintDataset(global, args.out, frames, "raw frames in");
}

void RunRectifyDataset(const RawArgs& args, const GlobalOptions& global) {
  const runtime::RectifiedDataset written =
      runtime::RectifyRecording(args.dataset, args.ground, args.vehicle, args.out, args.overwrite);
  const camera::IdealCameraOptions& ideal = written.ideal;
  char scale[96];
  std::snprintf(scale, sizeof(scale), " (%dx%d at %.4f mm/px)", ideal.width_px, ideal.height_px, ideal.mm_per_px);
  PrintDataset(global, args.out, written.frames, "frames rectified into", scale);
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

  auto drive_args = std::make_shared<runtime::CalibrationDriveJob>();
  CLI::App* drive = command->add_subcommand("simulate-drive", "A simulated calibration drive with known truth");
  drive->add_option("--out", drive_args->out, "Dataset directory to write")->required();
  std::map<std::string, core::DriveKind> kinds;
  for (const core::DriveKind kind : core::kDriveKinds) kinds[core::ToString(kind)] = kind;
  drive->add_option("--kind", drive_args->kind,
                    "The vehicle: differential (the default) or tricycle, which pivots with its steered wheel across")
      ->transform(CLI::CheckedTransformer(kinds));
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
