#include "mosaicloc/mapping/map_extension.hpp"

#include <cmath>
#include <map>
#include <memory>
#include <numbers>
#include <optional>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "mosaicloc/mosaic/builder.hpp"
#include "mosaicloc/mosaic/renderer.hpp"
#include "mosaicloc/sim/floor.hpp"
#include "mosaicloc/test/test_support.hpp"
#include "mosaicloc/tracking/reference.hpp"
#include "floor_view.hpp"

namespace mosaicloc::mapping {
namespace {

constexpr double kExtensionMmPerPx = 0.25;

// A stretch of floor off the map between two mapped places: frames every 30 mm along x from
// 100 to 640 mm, the map holding only the floor under the first and the last two.
class ExtensionDrive : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto texture = test::SharedTexture("asphalt_02_2048.jpg");
    if (!texture) GTEST_SKIP() << test::SharedDataMissingMessage();
    sim::ImageFloorOptions options;
    options.image = *texture;
    options.mm_per_texel = kExtensionMmPerPx;
    floor_image_ = sim::MakeImageFloor(options)->Render(0, 0, 3200, 2000);  // world (x, y) mm = texel (c, r) / 4
    for (int i = 0; i < 19; ++i) truth_.emplace_back(100.0 + 30.0 * i, 250.0, 0.0);
    mosaic::MapGrid grid;
    store_ = mosaic::TileStore::Create(scratch_.path() / "site.mosaic", grid);
    mosaic::MapBuilder builder(grid, mosaic::Blend::kFeather);
    for (const std::size_t i : {std::size_t{0}, truth_.size() - 2, truth_.size() - 1}) {
      builder.AddFrame(Frame(truth_[i]), truth_[i], kExtensionMmPerPx);
    }
    builder.Write(*store_);
    for (const mosaic::TileKey& key : store_->List(0)) before_[{key.col, key.row}] = store_->Read(key).pixels;
    cache_ = std::make_unique<mosaic::TileCache>(*store_);
  }

  cv::Mat Frame(const core::Pose2& world_from_camera) const {
    return test_views::FloorView(floor_image_, kExtensionMmPerPx, camera_, world_from_camera);
  }

  // The drive as the localizer would report it: a fix at the first frame, then visual
  // odometry whose every link is `bias` off (a drift), every frame a keyframe, and a fix on
  // the truth at the last frame back on the map. The start is known to `start_sigma_mm`. At
  // frame `break_at`, if given, the localizer's registration failed and it starts a new chain
  // where the wheels put it, `wheel_drift` off the truth. Frame `not_keyframe`, if given, is
  // registered but not kept as the keyframe, so the frame after it is registered against it,
  // as the localizer does where its keyframe does not register.
  void Drive(MapExtender& extender, const core::Pose2& bias, double start_sigma_mm = 0.01,
             std::optional<std::size_t> break_at = std::nullopt, const core::Pose2& wheel_drift = core::Pose2(),
             std::optional<std::size_t> not_keyframe = std::nullopt) {
    core::Pose2 chained = truth_.front();
    Eigen::Matrix3d covariance = Eigen::Vector3d(start_sigma_mm * start_sigma_mm, start_sigma_mm * start_sigma_mm, 1e-8).asDiagonal();
    for (std::size_t i = 0; i < truth_.size(); ++i) {
      ExtensionFrame frame;
      frame.time = core::Timestamp::FromSeconds(0.1 * static_cast<double>(i));
      frame.image = Frame(truth_[i]);
      frame.keyframe = !not_keyframe || i != *not_keyframe;
      if (i == 0 || i + 1 == truth_.size()) {
        frame.fixed = true;
        frame.world_from_camera = truth_[i];
      } else if (break_at && i == *break_at) {
        chained = truth_[i] * wheel_drift;
        covariance += Eigen::Vector3d(0.04, 0.04, 1e-6).asDiagonal();
        frame.world_from_camera = chained;
      } else {
        tracking::FrameLink link;
        link.earlier_time = core::Timestamp::FromSeconds(0.1 * static_cast<double>(i - 1));
        link.earlier_from_camera = Between(truth_[i - 1], truth_[i]) * bias;
        link.covariance = Eigen::Vector3d(1e-4, 1e-4, 1e-9).asDiagonal();
        chained = chained * link.earlier_from_camera;
        covariance += link.covariance;
        frame.world_from_camera = chained;
        frame.link = link;
      }
      frame.covariance = covariance;
      extender.Frame(frame);
    }
    extender.Finish();
  }

  // Every keyframe the extender painted is within `tolerance_mm` of its true pose (frames 0.1 s
  // apart from time 0).
  void ExpectPaintedWithin(const MapExtender& extender, double tolerance_mm) const {
    for (const auto& [time, pose] : extender.painted()) {
      const auto i = static_cast<std::size_t>(std::lround(core::ToSeconds(time - core::Timestamp()) / 0.1));
      ASSERT_LT(i, truth_.size());
      EXPECT_LT(core::Distance(pose, truth_[i]), tolerance_mm) << "frame " << i;
    }
  }

  const camera::IdealCamera camera_{camera::IdealCameraOptions{}};
  test::ScratchDir scratch_;
  cv::Mat floor_image_;
  std::vector<core::Pose2> truth_;
  std::unique_ptr<mosaic::TileStore> store_;
  std::unique_ptr<mosaic::TileCache> cache_;
  std::map<std::pair<std::int64_t, std::int64_t>, cv::Mat> before_;  ///< level-0 tiles (col, row) before the drive
};

// The stretch is painted at poses solved between the two mapped places: the drift its chain
// gathered (0.02 mm sideways a link, 0.34 mm in all) is taken out to within the return's own
// registration error, a frame in the middle registers against the
// new floor on its truth, and not one pixel mapped before changed.
TEST_F(ExtensionDrive, AStretchOffTheMapIsClosedOntoItAndPaintedWhereTheMapHadNoFloor) {
  MapExtender extender(*store_, *cache_, camera_, tracking::TrackerOptions{}, MapExtensionOptions{});
  Drive(extender, core::Pose2(0.0, 0.02, 0.0));
  const ExtensionSummary& s = extender.summary();
  EXPECT_EQ(s.segments, 1);
  EXPECT_EQ(s.closed, 1);
  EXPECT_EQ(s.keyframes, static_cast<std::int64_t>(truth_.size()) - 2);
  EXPECT_GT(s.tiles_written, 4);
  EXPECT_NEAR(s.closure_max_mm, 0.02 * static_cast<double>(truth_.size() - 2), 0.03);
  EXPECT_TRUE(s.warnings.empty()) << s.warnings.front();
  // The stretch is one update in the map's history: `map revert` can undo it.
  const std::vector<mosaic::MapUpdate> history = store_->History();
  ASSERT_EQ(history.size(), 1u);
  EXPECT_NE(history.front().reason.find("automatic mapping"), std::string::npos) << history.front().reason;
  EXPECT_EQ(history.front().tiles, s.tiles_written);
  ExpectPaintedWithin(extender, 0.02);
  // The tracker finds a frame in the middle on the new floor, where it is.
  const mosaic::MapRenderer renderer(*cache_);
  const tracking::MapReference reference(renderer, 0);
  const tracking::Tracker tracker(camera_, tracking::TrackerOptions{});
  const core::Pose2 middle = truth_[truth_.size() / 2];
  const tracking::TrackResult found = tracker.Track(
      Frame(middle), middle * core::Pose2(0.5, -0.3, 0.001), Eigen::Vector3d(1.0, 1.0, 1e-4).asDiagonal(), reference);
  ASSERT_TRUE(found.ok()) << found.reason;
  EXPECT_LT(core::Distance(found.world_from_camera, middle), 0.02);
  // The floor the map had is as it was.
  for (const auto& [index, pixels] : before_) {
    const mosaic::TileRead now = store_->Read(mosaic::TileKey{0, index.first, index.second});
    ASSERT_EQ(now.status, mosaic::TileStatus::kOk);
    const cv::Mat mapped = pixels != mosaic::kUnmapped;
    cv::Mat changed;
    cv::bitwise_and(now.pixels != pixels, mapped, changed);
    EXPECT_EQ(cv::countNonZero(changed), 0) << "tile " << index.first << ", " << index.second;
  }
}

// A return millimetres from where the chain put it (0.2 mm along the lane a link, 3.4 mm in all:
// the chain's scale off by 0.7 %) is taken out: the chain bends onto the map at both ends, and
// what is left where the stretch meets the floor it returned onto is the return's own share of
// the least-squares fit, 0.05 mm (under a robust loss on the return it was 2.4 mm: a seam).
TEST_F(ExtensionDrive, AReturnMillimetresOffIsTakenOutInFull) {
  MapExtender extender(*store_, *cache_, camera_, tracking::TrackerOptions{}, MapExtensionOptions{});
  Drive(extender, core::Pose2(0.2, 0.0, 0.0));
  const ExtensionSummary& s = extender.summary();
  EXPECT_EQ(s.closed, 1);
  EXPECT_NEAR(s.closure_max_mm, 0.2 * static_cast<double>(truth_.size() - 2), 0.05);
  ASSERT_EQ(extender.painted().size(), truth_.size() - 2);
  ExpectPaintedWithin(extender, 0.06);
}

// The localizer's chain breaks in the middle of the stretch and starts again where the wheels
// put it, 0.8 mm and 0.05° off: the stretch registers across the break and goes on, so the
// wheels' error is not painted into the map (started afresh there, the stretch after the
// break would begin 0.8 mm off and leave a seam).
TEST_F(ExtensionDrive, ABreakInTheChainIsBridged) {
  MapExtender extender(*store_, *cache_, camera_, tracking::TrackerOptions{}, MapExtensionOptions{});
  Drive(extender, core::Pose2(), 0.01, truth_.size() / 2, core::Pose2(0.6, -0.5, 0.05 * std::numbers::pi / 180.0));
  const ExtensionSummary& s = extender.summary();
  EXPECT_EQ(s.bridged, 1);
  EXPECT_EQ(s.segments, 1);
  EXPECT_EQ(s.closed, 1);
  EXPECT_TRUE(s.warnings.empty()) << s.warnings.front();
  ASSERT_EQ(extender.painted().size(), truth_.size() - 2);
  ExpectPaintedWithin(extender, 0.02);
}

// The localizer registered a frame against the frame before it, not its keyframe (which it
// no longer overlapped enough): that frame joins the stretch as a node, the chain goes on
// unbroken, and the stretch is closed onto the map as a whole.
TEST_F(ExtensionDrive, AKeyframeRegisteredToTheFrameBeforeContinuesTheStretch) {
  MapExtender extender(*store_, *cache_, camera_, tracking::TrackerOptions{}, MapExtensionOptions{});
  Drive(extender, core::Pose2(0.0, 0.02, 0.0), 0.01, std::nullopt, core::Pose2(), truth_.size() / 2);
  const ExtensionSummary& s = extender.summary();
  EXPECT_EQ(s.segments, 1);
  EXPECT_EQ(s.closed, 1);
  EXPECT_EQ(s.bridged, 0);
  EXPECT_TRUE(s.warnings.empty()) << s.warnings.front();
  ASSERT_EQ(extender.painted().size(), truth_.size() - 2) << "the frame before is painted too";
  ExpectPaintedWithin(extender, 0.02);
}

// A start whose pose is not known well enough is never built on.
TEST_F(ExtensionDrive, NothingIsMappedFromAnUnconfidentStart) {
  MapExtender extender(*store_, *cache_, camera_, tracking::TrackerOptions{}, MapExtensionOptions{});
  Drive(extender, core::Pose2(), /*start_sigma_mm=*/5.0);
  EXPECT_EQ(extender.summary().segments, 0);
  EXPECT_EQ(extender.summary().tiles_written, 0);
  EXPECT_EQ(extender.summary().unanchored, static_cast<std::int64_t>(truth_.size()) - 2);
  ASSERT_EQ(extender.summary().warnings.size(), 1u);
  EXPECT_NE(extender.summary().warnings.front().find("max_anchor_sigma_mm"), std::string::npos);
}

// A stretch longer than max_segment_m is committed in pieces as it goes, each held at its start.
TEST_F(ExtensionDrive, ALongStretchIsCommittedAsItGoes) {
  MapExtensionOptions options;
  options.max_segment_m = 0.2;
  MapExtender extender(*store_, *cache_, camera_, tracking::TrackerOptions{}, options);
  Drive(extender, core::Pose2());
  EXPECT_GE(extender.summary().segments, 3);
  EXPECT_EQ(extender.summary().closed, 1) << "the last piece ends back on the map";
  EXPECT_EQ(extender.summary().keyframes, static_cast<std::int64_t>(truth_.size()) - 2);
}

TEST(MapExtensionOptions, BadValuesAreRefused) {
  MapExtensionOptions options;
  options.max_segment_m = 0.0;
  std::string why;
  EXPECT_FALSE(options.Check(&why));
  EXPECT_NE(why.find("max_segment_m"), std::string::npos);
}

}  // namespace
}  // namespace mosaicloc::mapping
