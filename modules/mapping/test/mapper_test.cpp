#include "mosaicloc/mapping/mapper.hpp"

#include <cmath>
#include <numbers>
#include <random>

#include <Eigen/LU>
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/sim/floor.hpp"
#include "mosaicloc/test/test_support.hpp"

namespace mosaicloc::mapping {
namespace {

constexpr double kMmPerPx = 0.25;

// A mapping drive rendered from a real floor texture: the camera (the vehicle itself,
// vehicle_from_camera the identity) on a circle of 120 mm radius, 6 mm a frame, and wheels
// whose distance is 2 % long and whose turning 2.5 % strong.
class MappingDrive : public ::testing::Test {
 protected:
  // The floor is the texture at the camera's resolution, or a `period_px` square of it tiled.
  void MakeFloor(int period_px = 0) {
    const auto texture = test::SharedTexture("asphalt_02_2048.jpg");
    if (!texture) GTEST_SKIP() << test::SharedDataMissingMessage();
    sim::ImageFloorOptions options;
    options.image = *texture;
    options.mm_per_texel = kMmPerPx;
    if (period_px > 0) {
      const cv::Mat t = cv::imread(texture->string(), cv::IMREAD_GRAYSCALE);
      ASSERT_FALSE(t.empty());
      options.image = scratch_ / "tile.png";
      ASSERT_TRUE(cv::imwrite(options.image.string(), t(cv::Rect(0, 0, period_px, period_px))));
    }
    floor_image_ = sim::MakeImageFloor(options)->Render(0, 0, 2000, 2000);  // world (x, y) mm = texel (c, r) / 4
  }

  static std::vector<core::Pose2> Circle(int frames) {
    std::vector<core::Pose2> truth;
    for (int i = 0; i < frames; ++i) {
      const double a = 0.05 * i;
      truth.emplace_back(250.0 + 120.0 * std::cos(a), 250.0 + 120.0 * std::sin(a), a + std::numbers::pi / 2.0);
    }
    return truth;
  }

  // The drive along `truth`; the frames in [gap_first, gap_last) cannot be read.
  MappingInput Input(const std::vector<core::Pose2>& truth, int gap_first = -1, int gap_last = -1) {
    MappingInput input;
    input.camera = camera::IdealCamera(camera::IdealCameraOptions{});
    input.start = truth.front();
    for (std::size_t i = 0; i < truth.size(); ++i) {
      input.frame_times.push_back(core::Timestamp::FromNanoseconds(static_cast<std::int64_t>(i) * 20'000'000));
      if (i == 0) {
        input.wheels.push_back(core::Pose2(5.0, -3.0, 0.2));
      } else {
        const core::Pose2 step = core::Between(truth[i - 1], truth[i]);
        input.wheels.push_back(input.wheels.back() *
                               core::Pose2(1.02 * step.x_mm(), 1.02 * step.y_mm(), 1.025 * step.yaw_rad()));
      }
    }
    const camera::IdealCamera camera = input.camera;
    const cv::Mat floor = floor_image_;
    input.load_frame = [truth, camera, floor, gap_first, gap_last](std::size_t i) {
      if (static_cast<int>(i) >= gap_first && static_cast<int>(i) < gap_last) return cv::Mat();
      const Eigen::Matrix<double, 2, 3> world = camera.PixelToWorldAffine(truth[i]);
      const cv::Mat texel_from_pixel = (cv::Mat_<double>(2, 3) << world(0, 0) / kMmPerPx, world(0, 1) / kMmPerPx,
                                        world(0, 2) / kMmPerPx, world(1, 0) / kMmPerPx, world(1, 1) / kMmPerPx,
                                        world(1, 2) / kMmPerPx);
      cv::Mat frame;
      cv::warpAffine(floor, frame, texel_from_pixel, cv::Size(camera.width_px(), camera.height_px()),
                     cv::INTER_CUBIC | cv::WARP_INVERSE_MAP);
      cv::Mat noise(frame.size(), CV_16SC1);
      cv::randn(noise, 0.0, 2.0);
      frame.convertTo(frame, CV_16SC1);
      frame += noise;
      frame.convertTo(frame, CV_8UC1);
      return frame;
    };
    return input;
  }

  static double MaxError(const std::vector<core::Pose2>& estimate, const std::vector<core::Pose2>& truth) {
    double worst = 0.0;
    for (std::size_t i = 0; i < truth.size(); ++i) worst = std::max(worst, core::Distance(estimate[i], truth[i]));
    return worst;
  }

  test::ScratchDir scratch_;
  cv::Mat floor_image_;
};

// A lap and a quarter: the chain drifts, the second pass over the first quarter closes loops,
// and the graph brings every frame back onto the truth with seams of a few thousandths of a
// pixel.
TEST_F(MappingDrive, ALoopedDriveIsMappedOntoTheTruth) {
  MakeFloor();
  if (IsSkipped()) return;
  const std::vector<core::Pose2> truth = Circle(160);
  const MappingResult r = MapPoses(Input(truth), MapperOptions{});
  EXPECT_EQ(r.frames, 160);
  EXPECT_EQ(r.registered, 159);
  EXPECT_GT(r.keyframe_edges, 100);
  EXPECT_GE(r.loops_accepted, 3);
  EXPECT_TRUE(r.warnings.empty()) << r.warnings.front();
  EXPECT_TRUE(r.gaps.empty());
  EXPECT_EQ(r.pieces, 1);
  EXPECT_TRUE(r.optimize.converged) << r.optimize.message;
  EXPECT_NEAR(r.path_length_m, 0.954, 0.01);
  for (const LoopClosure& loop : r.loops) {
    if (!loop.accepted) continue;
    EXPECT_GT(loop.mean_zncc, 0.9);
    EXPECT_LT(loop.chi2, 16.27);
  }
  const double chained = MaxError(r.chained_world_from_vehicle, truth);
  const double optimized = MaxError(r.world_from_vehicle, truth);
  EXPECT_LT(optimized, 0.1);
  EXPECT_LT(optimized, chained) << "the loops take out drift";
  double worst_seam = 0.0;
  for (const Seam& s : r.seams) worst_seam = std::max(worst_seam, s.after_px);
  EXPECT_LT(worst_seam, 0.1);
  EXPECT_EQ(r.graph.nodes.size(), 160U);
  // Every registration's yaw is held no surer than the floor over the share of the view its two
  // frames have in common: a keyframe link that rests on half the view counts half as sure.
  const MapperOptions defaults;
  const camera::IdealCamera camera(camera::IdealCameraOptions{});
  int shared_little = 0;
  for (const PoseGraphEdge& e : r.graph.edges) {
    const Eigen::Vector2d t = e.from_T_to.translation_mm();
    const double overlap = (1.0 - std::abs(t.x()) / camera.width_mm()) * (1.0 - std::abs(t.y()) / camera.height_mm());
    const double floor_rad = defaults.edge_min_sigma_deg * std::numbers::pi / 180.0 / std::max(overlap, 0.1);
    EXPECT_GE(e.information.inverse()(2, 2), 0.999 * floor_rad * floor_rad) << e.from << " -> " << e.to;
    if (overlap < 0.7) ++shared_little;
  }
  EXPECT_GT(shared_little, 10) << "keyframe links that share less than 0.7 of the view";
}

// The camera's height and tilt estimated from the registrations (the default): ideal views
// straight down at the calibrated height do not show either, so every registration is left as
// it was and the map is the one made without the estimation.
TEST_F(MappingDrive, AFlatFloorsViewsAreLeftAtTheCalibratedHeightAndStraightDown) {
  MakeFloor();
  if (IsSkipped()) return;
  const std::vector<core::Pose2> truth = Circle(160);
  cv::theRNG().state = 29;  // the frames' noise, the same in both runs
  const MappingResult r = MapPoses(Input(truth), MapperOptions{});
  ASSERT_EQ(r.view.scale.size(), 160U);
  ASSERT_EQ(r.view.tilt.size(), 160U);
  EXPECT_FALSE(r.view.height_applied) << r.view.height_agreement;
  EXPECT_FALSE(r.view.tilt_applied) << r.view.tilt_agreement.transpose();
  MapperOptions flat;
  flat.view_geometry = false;
  cv::theRNG().state = 29;
  const MappingResult without = MapPoses(Input(truth), flat);
  EXPECT_TRUE(without.view.scale.empty());
  ASSERT_EQ(without.world_from_vehicle.size(), r.world_from_vehicle.size());
  for (std::size_t i = 0; i < r.world_from_vehicle.size(); ++i) {
    EXPECT_EQ(core::Distance(r.world_from_vehicle[i], without.world_from_vehicle[i]), 0.0) << i;
  }
}

// A frame that cannot be read: the next one is not registered against the one before it (a
// whole step further back than the wheels say); the keyframe carries the chain over it.
TEST_F(MappingDrive, AnUnreadableFrameIsStepped) {
  MakeFloor();
  if (IsSkipped()) return;
  const std::vector<core::Pose2> truth = Circle(160);
  const MappingResult r = MapPoses(Input(truth, 50, 51), MapperOptions{});
  EXPECT_EQ(r.has_pose[50], 0);
  EXPECT_EQ(r.registered, 157) << "frames 50 and 51 have no predecessor to register against";
  EXPECT_TRUE(r.gaps.empty()) << "frame 51 registered against its keyframe";
  EXPECT_EQ(r.pieces, 1);
  double worst = 0.0;
  for (std::size_t i = 0; i < truth.size(); ++i) {
    if (r.has_pose[i]) worst = std::max(worst, core::Distance(r.world_from_vehicle[i], truth[i]));
  }
  EXPECT_LT(worst, 0.1);
}

// Over a floor that repeats every 32 mm, with frames lost so that the wheels carry the chain
// for 120 mm: the second pass sees a copy of the place a period away wherever it looks.
// A loop is closed only where it is the place itself, and every frame stays within a
// fraction of a period of the truth.
TEST_F(MappingDrive, ARepeatingFloorNeverClosesAWrongLoop) {
  MakeFloor(128);
  if (IsSkipped()) return;
  const std::vector<core::Pose2> truth = Circle(160);
  MapperOptions options;
  options.wheel_sigma_mm = 0.5;  // so that the loops after the gap are tried, not ruled out
  const MappingResult r = MapPoses(Input(truth, 40, 60), options);
  ASSERT_EQ(r.gaps.size(), 1U);
  EXPECT_EQ(r.gaps[0].first, 39);
  EXPECT_EQ(r.gaps[0].last, 60);
  EXPECT_EQ(r.has_pose[45], 0);
  // The loops back over the first piece are refused, so nothing but the wheels joins the two.
  EXPECT_EQ(r.pieces, 2);
  int rejected = 0;
  for (const LoopClosure& loop : r.loops) {
    if (!loop.accepted) {
      ++rejected;
      EXPECT_FALSE(loop.rejected.empty());
      continue;
    }
    const core::Pose2 measured = r.graph.nodes[loop.earlier].Inverse() * r.graph.nodes[loop.later];
    EXPECT_LT(core::Distance(measured, core::Between(truth[loop.earlier], truth[loop.later])), 1.0)
        << "loop " << loop.earlier << "-" << loop.later;
  }
  EXPECT_GT(rejected, 0) << "the loops over the copies are refused";
  for (std::size_t i = 0; i < truth.size(); ++i) {
    if (!r.has_pose[i]) continue;
    EXPECT_LT(core::Distance(r.world_from_vehicle[i], truth[i]), 8.0) << "frame " << i;
  }
  bool warned_gap = false, warned_pieces = false;
  for (const std::string& w : r.warnings) {
    warned_gap |= w.find("frames 39 to 60") != std::string::npos;
    warned_pieces |= w.find("2 pieces") != std::string::npos;
  }
  EXPECT_TRUE(warned_gap);
  EXPECT_TRUE(warned_pieces);
}

// Two drives over the same floor, the second started where its vehicle was only roughly
// known to be (10 mm and 0.5 degrees off): loop closures onto the first drive's frames place
// it, and both come out on the truth as one piece.
TEST_F(MappingDrive, ALaterDriveIsJoinedToTheFirst) {
  MakeFloor();
  if (IsSkipped()) return;
  std::vector<core::Pose2> truth = Circle(130);
  for (int i = 0; i < 90; ++i) {
    const double a = 1.0 + 0.05 * i;
    truth.emplace_back(265.0 + 120.0 * std::cos(a), 245.0 + 120.0 * std::sin(a), a + std::numbers::pi / 2.0);
  }
  MappingInput input = Input(truth);
  LaterDrive later;
  later.first = 130;
  later.start = truth[130] * core::Pose2(8.0, -6.0, 0.5 * std::numbers::pi / 180.0);
  input.later_drives.push_back(later);
  const MappingResult r = MapPoses(input, MapperOptions{});
  int joining = 0;
  for (const LoopClosure& loop : r.loops) joining += loop.accepted && loop.earlier < 130 && loop.later >= 130 ? 1 : 0;
  EXPECT_GE(joining, 3);
  EXPECT_EQ(r.pieces, 1);
  EXPECT_TRUE(r.gaps.empty());
  EXPECT_EQ(r.registered, 218) << "every frame but the drives' first to its predecessor";
  EXPECT_LT(core::Distance(r.chained_world_from_vehicle[130], truth[130]), 11.0) << "placed by its start";
  EXPECT_LT(MaxError(r.world_from_vehicle, truth), 0.15);
  EXPECT_NEAR(r.path_length_m, 0.775 + 0.534, 0.02);
}

TEST_F(MappingDrive, LaterDrivesMustFollowOneAnother) {
  MakeFloor();
  if (IsSkipped()) return;
  MappingInput input = Input(Circle(20));
  input.later_drives.push_back({10, core::Pose2(), 20.0, 1.0});
  input.later_drives.push_back({5, core::Pose2(), 20.0, 1.0});
  EXPECT_THROW(MapPoses(input, MapperOptions{}), core::Error);
  input.later_drives = {{25, core::Pose2(), 20.0, 1.0}};
  EXPECT_THROW(MapPoses(input, MapperOptions{}), core::Error);
  input.later_drives = {{10, core::Pose2(), 0.0, 1.0}};
  EXPECT_THROW(MapPoses(input, MapperOptions{}), core::Error);
}

// A drive that never comes back over its floor is mapped, with a warning that nothing bounds
// its drift.
TEST_F(MappingDrive, ADriveThatNeverComesBackIsMappedWithAWarning) {
  MakeFloor();
  if (IsSkipped()) return;
  const std::vector<core::Pose2> truth = Circle(30);
  const MappingResult r = MapPoses(Input(truth), MapperOptions{});
  EXPECT_EQ(r.loops_accepted, 0);
  ASSERT_EQ(r.warnings.size(), 1U);
  EXPECT_NE(r.warnings[0].find("no loop closed"), std::string::npos) << r.warnings[0];
  EXPECT_LT(MaxError(r.world_from_vehicle, truth), 0.5);
}

TEST(Mapper, BadInputIsRejected) {
  MappingInput input;
  EXPECT_THROW(MapPoses(input, MapperOptions{}), core::Error) << "no frames";
  input.frame_times.push_back(core::Timestamp::FromNanoseconds(0));
  EXPECT_THROW(MapPoses(input, MapperOptions{}), core::Error) << "no wheels";
  MapperOptions options;
  options.keyframe_fraction = 1.5;
  std::string why;
  EXPECT_FALSE(options.Check(&why));
  EXPECT_NE(why.find("keyframe_fraction"), std::string::npos);
  options = MapperOptions{};
  options.loop_max_search_px = 1;
  EXPECT_FALSE(options.Check(&why));
  options = MapperOptions{};
  options.keyframe_sigma_deg = 0.0;
  EXPECT_FALSE(options.Check(&why));
  EXPECT_NE(why.find("keyframe sigmas"), std::string::npos);
}

}  // namespace
}  // namespace mosaicloc::mapping
