// Per-frame cost of registration and of its parts, on one core.
// Run: OPENCV_FOR_THREADS_NUM=1 taskset -c 0 build/.../benchmarks/mosaicloc_tracking_benchmark
#include <cmath>
#include <numbers>

#include <benchmark/benchmark.h>
#include <opencv2/core.hpp>

#include "mosaicloc/sim/floor.hpp"
#include "mosaicloc/sim/resample.hpp"
#include "mosaicloc/tracking/tracker.hpp"

namespace mosaicloc {
namespace {

using Affine = Eigen::Matrix<double, 2, 3>;
constexpr double kMmPerPx = 0.25;
constexpr double kDeg = std::numbers::pi / 180.0;

// Procedural concrete at 0.125 mm/texel, seen by the 0.25 mm/px ideal camera: a reference
// image (the "map") and a live frame offset by 1.3 px, -0.7 px and 0.4 degrees.
struct Scene {
  Scene() : camera(camera::IdealCameraOptions{}) {
    sim::ProceduralFloorOptions floor_options;
    floor_options.mm_per_texel = 0.125;
    const auto floor = sim::MakeProceduralFloor(floor_options);
    texture = floor->Render(0, 0, 2200, 1900);
    source_from_reference << 2.0, 0.0, 80.5, 0.0, 2.0, 80.5;
    sim::ResampleExact(texture, source_from_reference, cv::Size(960, 800), 2).convertTo(reference_image, CV_8UC1);
    reference = std::make_unique<tracking::ImageReference>(reference_image, core::Pose2::Identity(), kMmPerPx);
    truth = core::Pose2(1.3 * kMmPerPx, -0.7 * kMmPerPx, 0.4 * kDeg);
    const Affine reference_from_view =
        tracking::ComposeAffine(reference->WorldToRaster(), camera.PixelToWorldAffine(truth));
    cv::Mat exact = sim::ResampleExact(texture, tracking::ComposeAffine(source_from_reference, reference_from_view),
                                       cv::Size(640, 480), 2);
    cv::Mat noise(exact.size(), CV_32FC1);
    cv::RNG(1).fill(noise, cv::RNG::NORMAL, 0.0, 2.0);
    exact += noise;
    exact.convertTo(frame, CV_8UC1);
  }
  camera::IdealCamera camera;
  cv::Mat texture, reference_image, frame;
  Affine source_from_reference;
  std::unique_ptr<tracking::ImageReference> reference;
  core::Pose2 truth;
};

const Scene& GetScene() {
  static const Scene scene;
  return scene;
}

Eigen::Matrix3d Prior(double sigma_px, double sigma_deg) {
  return Eigen::Vector3d(std::pow(sigma_px * kMmPerPx, 2), std::pow(sigma_px * kMmPerPx, 2),
                         std::pow(sigma_deg * kDeg, 2))
      .asDiagonal();
}

void BM_SelectTemplates(benchmark::State& state) {
  const Scene& s = GetScene();
  tracking::TemplateOptions options;
  for (auto _ : state) benchmark::DoNotOptimize(tracking::SelectTemplates(s.frame, options));
}
BENCHMARK(BM_SelectTemplates)->Unit(benchmark::kMicrosecond);

void BM_SearchZncc(benchmark::State& state) {
  const Scene& s = GetScene();
  const int range = static_cast<int>(state.range(0));
  const cv::Mat templ = s.frame(cv::Rect(200, 150, 96, 96));
  const cv::Mat window = s.reference_image(cv::Rect(360 - range, 310 - range, 96 + 2 * range, 96 + 2 * range));
  for (auto _ : state) benchmark::DoNotOptimize(tracking::SearchZncc(templ, window, tracking::SearchOptions{}));
}
BENCHMARK(BM_SearchZncc)->Arg(4)->Arg(12)->Arg(24)->Arg(64)->Unit(benchmark::kMicrosecond);

void BM_RefineDirect(benchmark::State& state) {
  const Scene& s = GetScene();
  const Affine frame_to_raster =
      tracking::ComposeAffine(s.reference->WorldToRaster(), s.camera.PixelToWorldAffine(core::Pose2::Identity()));
  tracking::RefineOptions options;
  int iterations = 0;
  for (auto _ : state) {
    const tracking::RefinedMatch m =
        tracking::RefineTemplate(s.frame, cv::Rect(200, 150, 96, 96), *s.reference, frame_to_raster, options);
    iterations = m.iterations;
    benchmark::DoNotOptimize(m);
  }
  state.counters["iterations"] = iterations;
}
BENCHMARK(BM_RefineDirect)->Unit(benchmark::kMicrosecond);

// The pose from N correspondences (arg 0: 4 at the default template spots, or 20 spread over
// the view), with one false match 2 mm off among them when arg 1 is 1: the robust solver
// against the founding paper's Kalman observer.
void BM_SolvePlanarPose(benchmark::State& state, tracking::PoseMethod method) {
  const Scene& s = GetScene();
  std::vector<tracking::Correspondence> cs;
  const int n = static_cast<int>(state.range(0));
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector2d p = n == 4 ? Eigen::Vector2d(i % 2 == 0 ? -50 : 50, i < 2 ? 30 : -30)
                                     : Eigen::Vector2d(-70.0 + 140.0 * (i % 5) / 4.0, -50.0 + 100.0 * (i / 5) / 3.0);
    cs.push_back({p, s.truth * p + Eigen::Vector2d(0.001 * ((i % 3) - 1), -0.001 * ((i % 2) * 2 - 1)), 0.002});
  }
  if (state.range(1) == 1) cs[1].world_mm += Eigen::Vector2d(2.0, 0.0);
  tracking::PoseSolverOptions options;
  options.method = method;
  for (auto _ : state) {
    const tracking::PoseSolution solution = tracking::SolvePlanarPose(cs, s.truth * core::Pose2(0.3, -0.2, 0.002), options);
    if (!solution.ok()) state.SkipWithError("no pose");
    benchmark::DoNotOptimize(solution);
  }
}
BENCHMARK_CAPTURE(BM_SolvePlanarPose, least_squares, tracking::PoseMethod::kLeastSquares)
    ->Args({4, 0})->Args({20, 0})->Args({20, 1})->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(BM_SolvePlanarPose, kalman_observer, tracking::PoseMethod::kKalmanObserver)
    ->Args({4, 0})->Args({20, 0})->Args({20, 1})->Unit(benchmark::kMicrosecond);

// Whole registration of one frame. Arg 0: tracking (prior 1 px, 0.1 deg, what the localizer
// gives in lock); arg 1: the registration benchmark's prior (2.7 px, 1 deg).
void BM_Track(benchmark::State& state, tracking::TrackerOptions options) {
  const Scene& s = GetScene();
  const tracking::Tracker tracker(s.camera, options);
  const Eigen::Matrix3d prior = state.range(0) == 0 ? Prior(1.0, 0.1) : Prior(8.0 / 3.0, 1.0);
  for (auto _ : state) {
    const tracking::TrackResult r = tracker.Track(s.frame, core::Pose2::Identity(), prior, *s.reference);
    if (!r.ok()) state.SkipWithError(r.reason.c_str());
    benchmark::DoNotOptimize(r);
  }
}
BENCHMARK_CAPTURE(BM_Track, 4x96, tracking::TrackerOptions{})->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);
tracking::TrackerOptions Tiled() {
  tracking::TrackerOptions o;
  o.templates.mode = tracking::TemplateMode::kTiled;
  return o;
}
BENCHMARK_CAPTURE(BM_Track, whole_frame, Tiled())->Arg(0)->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace mosaicloc

BENCHMARK_MAIN();
