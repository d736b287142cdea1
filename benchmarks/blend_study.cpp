// Which blend gives the better map? Simulates a drive (noise, blur, vignetting, illumination
// change on), paints it with feathered and best-view blending, and compares views rendered
// from each map with the simulator's noise-free truth at the same poses.
//   mosaicloc_blend_study [--floor IMAGE] [--frames N]
#include <cstdio>
#include <filesystem>

#include <CLI/CLI.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "mosaicloc/dataset/dataset.hpp"
#include "mosaicloc/mosaic/builder.hpp"
#include "mosaicloc/mosaic/renderer.hpp"
#include "mosaicloc/sim/imaging.hpp"
#include "mosaicloc/sim/simulator.hpp"
#include "mosaicloc/test/test_support.hpp"
#include "mosaicloc/tracking/reference.hpp"
#include "mosaicloc/tracking/render_window.hpp"

namespace {

using namespace mosaicloc;

// Gradient energy of a over that of b, inside mask: below 1 means a is blurrier.
double Sharpness(const cv::Mat& a, const cv::Mat& b, const cv::Mat& mask) {
  const auto energy = [&](const cv::Mat& image) {
    cv::Mat gx, gy;
    cv::Sobel(image, gx, CV_32F, 1, 0);
    cv::Sobel(image, gy, CV_32F, 0, 1);
    cv::Mat magnitude = gx.mul(gx) + gy.mul(gy);
    return cv::mean(magnitude, mask)[0];
  };
  return std::sqrt(energy(a) / energy(b));
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Feathered against best-view blending, measured against the true floor"};
  std::string floor = "procedural";
  std::int64_t frames = 300;
  app.add_option("--floor", floor, "procedural or an image file");
  app.add_option("--frames", frames, "Frames to simulate");
  CLI11_PARSE(app, argc, argv);

  const auto directory = std::filesystem::temp_directory_path() / "mosaicloc-blend-study";
  std::filesystem::remove_all(directory);
  sim::SimulatorOptions options;
  if (floor != "procedural") {
    options.floor.kind = "image";
    options.floor.image = floor;
  }
  options.frames = frames;
  sim::Simulate(options, directory, true);

  const dataset::DatasetReader reader(directory);
  const dataset::Trajectory groundtruth = reader.GroundTruth();
  mosaic::MapGrid grid;
  grid.levels = 1;
  mosaic::MapBuilder feather(grid, mosaic::Blend::kFeather);
  mosaic::MapBuilder best(grid, mosaic::Blend::kBestView);
  std::vector<core::Pose2> poses;
  auto stream = reader.Frames();
  while (const auto frame = stream.Next()) {
    const core::Pose2 pose =
        *dataset::PoseAt(groundtruth, frame->time, std::chrono::milliseconds(1)) * options.vehicle_from_camera;
    feather.AddFrame(frame->image, pose, grid.mm_per_px);
    best.AddFrame(frame->image, pose, grid.mm_per_px);
    poses.push_back(pose);
  }
  const auto floor_model = sim::MakeFloor(options.floor);
  const camera::IdealCamera camera(options.camera);
  const sim::Imager truth(*floor_model, camera, options.imaging, options.seed);

  std::printf("floor %s, %zu frames; views at every 10th pose against the noise-free truth\n", floor.c_str(), poses.size());
  std::printf("%-10s %10s %10s %12s\n", "blend", "ZNCC mean", "ZNCC min", "sharpness");
  for (const auto& [name, builder] : {std::pair<const char*, mosaic::MapBuilder*>{"feather", &feather}, {"best-view", &best}}) {
    const auto file = directory / (std::string(name) + ".mosaic");
    std::filesystem::remove(file);
    {
      auto store = mosaic::TileStore::Create(file, grid);
      builder->Write(*store);
    }
    auto store = mosaic::TileStore::Open(file, false);
    mosaic::TileCache cache(*store);
    const mosaic::MapRenderer renderer(cache);
    const tracking::MapReference reference(renderer, 0);
    double zncc_sum = 0, zncc_min = 1, sharp_sum = 0;
    int n = 0;
    for (std::size_t i = 5; i + 5 < poses.size(); i += 10) {
      cv::Mat mask;
      const cv::Mat view = tracking::RenderCameraView(reference, camera, poses[i], &mask);
      const cv::Mat clean = truth.RenderClean(poses[i]);
      const double z = test::Zncc(view, clean, mask);
      zncc_sum += z;
      zncc_min = std::min(zncc_min, z);
      sharp_sum += Sharpness(view, clean, mask);
      ++n;
    }
    std::printf("%-10s %10.4f %10.4f %12.3f\n", name, zncc_sum / n, zncc_min, sharp_sum / n);
  }
  std::filesystem::remove_all(directory);
  return 0;
}
