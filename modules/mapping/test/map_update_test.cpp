#include "mosaicloc/mapping/map_update.hpp"

#include <cmath>
#include <map>
#include <memory>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "mosaicloc/mosaic/builder.hpp"
#include "mosaicloc/mosaic/renderer.hpp"
#include "mosaicloc/sim/floor.hpp"
#include "mosaicloc/test/test_support.hpp"
#include "floor_view.hpp"

namespace mosaicloc::mapping {
namespace {

constexpr double kUpdateMmPerPx = 0.25;

// A lane mapped from a floor that has changed since: a square of it, 40 mm on a side around
// (400, 250) mm, is new floor (another part of the texture), as after a tile was replaced.
class ChangedLane : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto texture = test::SharedTexture("asphalt_02_2048.jpg");
    if (!texture) GTEST_SKIP() << test::SharedDataMissingMessage();
    sim::ImageFloorOptions options;
    options.image = *texture;
    options.mm_per_texel = kUpdateMmPerPx;
    floor_ = sim::MakeImageFloor(options)->Render(0, 0, 3200, 2000);  // world (x, y) mm = texel (c, r) / 4
    changed_ = floor_.clone();
    floor_(cv::Rect(2400, 1400, 160, 160)).copyTo(changed_(changed_square_));
    for (int i = 0; i < 17; ++i) lane_.emplace_back(150.0 + 30.0 * i, lane_y_mm_, 0.0);
    store_ = mosaic::TileStore::Create(scratch_.path() / "site.mosaic", mosaic::MapGrid{});
    mosaic::MapBuilder builder(mosaic::MapGrid{}, mosaic::Blend::kFeather);
    for (const core::Pose2& pose : lane_) builder.AddFrame(Frame(floor_, pose), pose, kUpdateMmPerPx);
    builder.Write(*store_);
    for (const mosaic::TileKey& key : store_->List()) before_[{key.level, key.col, key.row}] = store_->Read(key).pixels;
    cache_ = std::make_unique<mosaic::TileCache>(*store_);
  }

  cv::Mat Frame(const cv::Mat& floor, const core::Pose2& world_from_camera) const {
    return test_views::FloorView(floor, kUpdateMmPerPx, camera_, world_from_camera);
  }

  // One pass along the lane over the changed floor, `start_s` seconds into the drive, frames
  // 0.1 s apart, each a confident fix at `error` from its truth (the image from the truth).
  void Pass(MapUpdater& updater, double start_s, const core::Pose2& error = core::Pose2(),
            double sigma_mm = 0.005, bool restarted_every_frame = false) {
    for (std::size_t i = 0; i < lane_.size(); ++i) {
      // Each pass a little to the side of the last, as a vehicle drives.
      const core::Pose2 truth = lane_[i] * core::Pose2(0.0, 2.0 * std::sin(start_s), 0.002 * std::cos(start_s));
      UpdateFrame frame;
      frame.time = core::Timestamp::FromSeconds(start_s + 0.1 * static_cast<double>(i));
      frame.image = Frame(changed_, truth);
      frame.world_from_camera = truth * error;
      frame.covariance = Eigen::Vector3d(sigma_mm * sigma_mm, sigma_mm * sigma_mm, 1e-10).asDiagonal();
      frame.fixed = true;
      frame.restarted = restarted_every_frame;
      frame.tracking = true;
      frame.nis = 1.5;
      updater.Frame(frame);
    }
  }

  // ZNCC of the map's level 0 against a floor over a box of world mm (x0, y0, x1, y1).
  double MapAgainst(const cv::Mat& floor, double x0, double y0, double x1, double y1) const {
    const mosaic::MapRenderer renderer(*cache_);
    const auto col0 = static_cast<std::int64_t>(std::floor(x0 / kUpdateMmPerPx));
    const auto row0 = static_cast<std::int64_t>(std::floor(-y1 / kUpdateMmPerPx));
    const int cols = static_cast<int>(std::lround((x1 - x0) / kUpdateMmPerPx));
    const int rows = static_cast<int>(std::lround((y1 - y0) / kUpdateMmPerPx));
    const mosaic::RasterPatch patch = renderer.Region(0, col0, row0, cols, rows);
    // Raster pixel (col, row) has its centre at world ((col + 0.5) r, -(row + 0.5) r): texel
    // (col + 0.5, -(row + 0.5)) of the floor.
    const cv::Mat texel_from_local = (cv::Mat_<double>(2, 3) << 1.0, 0.0, static_cast<double>(col0) + 0.5, 0.0, -1.0,
                                      -static_cast<double>(row0) - 0.5);
    cv::Mat expected;
    cv::warpAffine(floor, expected, texel_from_local, cv::Size(cols, rows), cv::INTER_CUBIC | cv::WARP_INVERSE_MAP);
    cv::Mat score;
    cv::matchTemplate(patch.image, expected, score, cv::TM_CCOEFF_NORMED);
    return score.at<float>(0, 0);
  }

  const camera::IdealCamera camera_{camera::IdealCameraOptions{}};
  test::ScratchDir scratch_;
  cv::Mat floor_, changed_;
  // Where the lane runs and where the floor changed; set before SetUp.
  double lane_y_mm_ = 250.0;            ///< the view covers 60 mm to either side of it
  cv::Rect changed_square_{1520, 920, 160, 160};  ///< texels: (380..420, 230..270) mm
  double MapAgainstNewFloor() const { return MapAgainst(changed_, 384.0, 234.0, 416.0, 266.0); }
  std::vector<core::Pose2> lane_;
  std::unique_ptr<mosaic::TileStore> store_;
  std::unique_ptr<mosaic::TileCache> cache_;
  std::map<std::tuple<int, std::int64_t, std::int64_t>, cv::Mat> before_;
};

// Seen changed on one pass, nothing is written; on the second the changed floor is painted
// over from the live view, in one update the history keeps; a third pass finds the map as the
// floor is, and reverting the update gives back the map as it was, pixel for pixel.
TEST_F(ChangedLane, ChangedFloorIsRewrittenOnTheSecondPassAndCanBeReverted) {
  ASSERT_LT(MapAgainstNewFloor(), 0.3) << "the map does not show the new floor yet";
  MapUpdater updater(*store_, *cache_, camera_, MapUpdateOptions{});
  Pass(updater, 0.0);
  EXPECT_EQ(updater.summary().updates, 0);
  EXPECT_GT(updater.summary().cells_pending, 0);
  EXPECT_TRUE(store_->History().empty());
  Pass(updater, 10.0);
  ASSERT_GE(updater.summary().updates, 1);
  EXPECT_GT(MapAgainstNewFloor(), 0.9) << "the map shows the new floor";
  // Floor that did not change is as it was: only cells over the square were written.
  EXPECT_GT(MapAgainst(floor_, 150.0, 220.0, 330.0, 280.0), 0.98);
  const mosaic::MapGrid grid;
  for (const auto& [key, pixels] : before_) {
    if (std::get<0>(key) != 0) continue;
    const cv::Mat now = store_->Read(mosaic::TileKey{0, std::get<1>(key), std::get<2>(key)}).pixels;
    std::vector<cv::Point> changed;
    cv::findNonZero(now != pixels, changed);
    for (const cv::Point& p : changed) {
      const Eigen::Vector2d world = grid.RasterToWorld(
          Eigen::Vector2d(static_cast<double>(std::get<1>(key) * 256 + p.x), static_cast<double>(std::get<2>(key) * 256 + p.y)), 0);
      // Within a cell (16 mm) of the new floor.
      ASSERT_TRUE(world.x() > 364.0 && world.x() < 436.0 && world.y() > 214.0 && world.y() < 286.0)
          << "changed at " << world.transpose();
    }
  }
  const std::vector<mosaic::MapUpdate> history = store_->History();
  ASSERT_EQ(static_cast<std::int64_t>(history.size()), updater.summary().updates);
  EXPECT_NE(history.front().reason.find("seen changed on 2 passes"), std::string::npos) << history.front().reason;
  const std::int64_t updates = updater.summary().updates;
  Pass(updater, 20.0);
  EXPECT_EQ(updater.summary().updates, updates) << "the map now shows the floor as it is";

  for (auto it = history.rbegin(); it != history.rend(); ++it) mosaic::RevertUpdate(*store_, it->id);
  for (const auto& [key, pixels] : before_) {
    const mosaic::TileRead now = store_->Read(mosaic::TileKey{std::get<0>(key), std::get<1>(key), std::get<2>(key)});
    ASSERT_EQ(now.status, mosaic::TileStatus::kOk);
    EXPECT_EQ(cv::norm(now.pixels, pixels, cv::NORM_INF), 0.0);
  }
}

// Nothing is ever written from a pose that is not confident: a fix 0.5 mm off (the view then
// disagrees with the map nearly everywhere, so it does not vote), a filter that keeps
// restarting, or a pose known only to 0.1 mm.
TEST_F(ChangedLane, NothingIsWrittenFromAnUnconfidentPose) {
  MapUpdater updater(*store_, *cache_, camera_, MapUpdateOptions{});
  for (int pass = 0; pass < 4; ++pass) Pass(updater, 10.0 * pass, core::Pose2(0.5, 0.0, 0.0));
  EXPECT_EQ(updater.summary().updates, 0);
  EXPECT_GT(updater.summary().mostly_changed, 0);
  for (int pass = 4; pass < 8; ++pass) Pass(updater, 10.0 * pass, core::Pose2(), 0.005, /*restarted_every_frame=*/true);
  for (int pass = 8; pass < 12; ++pass) Pass(updater, 10.0 * pass, core::Pose2(), /*sigma_mm=*/0.1);
  EXPECT_EQ(updater.summary().updates, 0);
  EXPECT_TRUE(store_->History().empty());
}

// Where the map's quality layer says the floor repeats, the view cannot tell the place from a
// copy of it: nothing is compared there, however confident the fix.
TEST_F(ChangedLane, NothingIsWrittenWhereTheFloorRepeats) {
  std::vector<mosaic::QualityCell> cells;
  for (std::int64_t row = -4; row <= 4; ++row) {
    for (std::int64_t col = -2; col <= 8; ++col) cells.push_back({col, row, 1.0f, 20.0f, 0.97f});
  }
  store_->WriteQuality(1, cells);
  MapUpdater updater(*store_, *cache_, camera_, MapUpdateOptions{});
  for (int pass = 0; pass < 3; ++pass) Pass(updater, 10.0 * pass);
  EXPECT_EQ(updater.summary().updates, 0);
  EXPECT_EQ(updater.summary().compared, 0);
  EXPECT_GT(updater.summary().repeating, 0);
  // Where it does not repeat, the layer changes nothing.
  for (mosaic::QualityCell& cell : cells) cell.ambiguity = 0.3f;
  store_->WriteQuality(1, cells);
  MapUpdater unique(*store_, *cache_, camera_, MapUpdateOptions{});
  for (int pass = 3; pass < 5; ++pass) Pass(unique, 10.0 * pass);
  EXPECT_GE(unique.summary().updates, 1);
}

// More passes asked for, more passes needed.
TEST_F(ChangedLane, TheNumberOfPassesIsTheOptions) {
  MapUpdateOptions options;
  options.passes = 3;
  MapUpdater updater(*store_, *cache_, camera_, options);
  Pass(updater, 0.0);
  Pass(updater, 10.0);
  EXPECT_EQ(updater.summary().updates, 0);
  Pass(updater, 20.0);
  EXPECT_GE(updater.summary().updates, 1);
}

// The same lane 4 mm further up, and the new floor at its edge: 40 mm square around (400, 310)
// mm, half of it outside the lane. The map's 16 mm cells at the edge are only partly mapped,
// as they are only partly in a view along the lane: they are judged on what both hold, and
// the part of the change the lane covers is rewritten.
class ChangedLaneEdge : public ChangedLane {
 protected:
  ChangedLaneEdge() {
    lane_y_mm_ = 254.0;                               // mapped up to y = 314 mm
    changed_square_ = cv::Rect(1520, 1160, 160, 160);  // texels: (380..420, 290..330) mm
  }
};

TEST_F(ChangedLaneEdge, ChangedFloorAtTheLanesEdgeIsRewrittenToo) {
  // The cell from y = 304 to 320 mm is mapped up to 314 (62 %); the view along the lane holds
  // about as much of it.
  ASSERT_LT(MapAgainst(changed_, 384.0, 305.0, 416.0, 311.0), 0.3) << "the map does not show the new floor yet";
  MapUpdater updater(*store_, *cache_, camera_, MapUpdateOptions{});
  // Passes 0 and 20 s run on or beyond the mapping drive's line (0 and +1.8 mm), and their
  // views hold the edge cells' mapped part; the one at 10 s runs 1.1 mm inside it.
  Pass(updater, 0.0);
  Pass(updater, 10.0);
  Pass(updater, 20.0);
  ASSERT_GE(updater.summary().updates, 1);
  EXPECT_GT(MapAgainst(changed_, 384.0, 292.0, 416.0, 303.0), 0.9) << "the change inside the lane";
  EXPECT_GT(MapAgainst(changed_, 384.0, 305.0, 416.0, 311.0), 0.9) << "the change in the edge's cells";
  // No more than the view held was painted: beyond the lane the map is still unmapped.
  const mosaic::MapRenderer renderer(*cache_);
  const mosaic::RasterPatch beyond = renderer.Region(0, static_cast<std::int64_t>(384.0 / kUpdateMmPerPx),
                                                     static_cast<std::int64_t>(-330.0 / kUpdateMmPerPx), 128, 40);
  EXPECT_EQ(cv::countNonZero(beyond.mask), 0) << "y 320 to 330 mm lies outside every view";
}

TEST(MapUpdateOptions, AJudgedShareOutsideZeroToOneIsRefused) {
  MapUpdateOptions options;
  std::string why;
  for (const double share : {0.0, 1.5}) {
    options.min_judged_share = share;
    EXPECT_FALSE(options.Check(&why));
    EXPECT_NE(why.find("min_judged_share"), std::string::npos);
  }
}

TEST(MapUpdateOptions, OnePassIsRefused) {
  MapUpdateOptions options;
  options.passes = 1;
  std::string why;
  EXPECT_FALSE(options.Check(&why));
  EXPECT_NE(why.find("passes"), std::string::npos);
}

}  // namespace
}  // namespace mosaicloc::mapping
