#include <algorithm>
#include <cmath>
#include <numbers>
#include <optional>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "mosaicloc/localizer/localizer.hpp"
#include "mosaicloc/mosaic/builder.hpp"
#include "mosaicloc/mosaic/renderer.hpp"
#include "mosaicloc/mosaic/tile_cache.hpp"
#include "mosaicloc/mosaic/tile_store.hpp"
#include "mosaicloc/tracking/place_index.hpp"
#include "mosaicloc/sim/floor.hpp"
#include "mosaicloc/sim/imaging.hpp"
#include "mosaicloc/sim/stance.hpp"
#include "mosaicloc/test/test_support.hpp"

namespace mosaicloc::localizer {
namespace {

using core::Pose2;
using core::Timestamp;

// A real texture laid on the floor at 0.125 mm/texel, its map written straight into a store
// (each map pixel the 2x2 average of the texels it covers, as a perfect mapping run would),
// and a vehicle driving over it with biased wheel odometry. The texture (256 mm square on
// the floor) is laid in its eight turned and mirrored versions, 4 x 2, so the floor repeats
// only every 1024 x 512 mm, beyond the mapped 896 x 384 mm: one place matches each view.
class Drive : public ::testing::Test {
 protected:
  virtual bool Repeating() const { return false; }
  /// The simulator's procedural floor, which never repeats (the composite below repeats its
  /// texture turned and mirrored, which a search over all headings sees as copies).
  virtual bool Procedural() const { return false; }
  /// The texture cut into patches at random places and turns (sim::ImageFloorOptions::layout),
  /// an asphalt floor that never repeats.
  virtual bool Patches() const { return false; }
  /// The map's extent in 256 px (64 mm) tiles, and a band of tile columns left unmapped.
  virtual int MapCols() const { return 14; }
  virtual int MapRows() const { return 6; }
  virtual bool Mapped(int /*col*/) const { return true; }
  /// Texels the map's tiles of a column are painted shifted by (a map that is not rigid).
  virtual cv::Point2i PaintedShift(int /*col*/) const { return {0, 0}; }

  void SetUp() override {
    const auto texture = test::SharedTexture("asphalt_02_2048.jpg");
    if (!texture) GTEST_SKIP() << test::SharedDataMissingMessage();
    sim::ImageFloorOptions floor_options;
    floor_options.image = *texture;
    floor_options.mm_per_texel = 0.125;
    if (Procedural()) {
      sim::ProceduralFloorOptions procedural;
      procedural.mm_per_texel = 0.125;
      floor_ = sim::MakeProceduralFloor(procedural);
    } else if (Patches()) {
      floor_options.layout = "patches";
    } else if (!Repeating()) {
      const cv::Mat t = cv::imread(texture->string(), cv::IMREAD_GRAYSCALE);
      ASSERT_FALSE(t.empty());
      cv::Mat composite(2 * t.rows, 4 * t.cols, CV_8UC1);
      for (int i = 0; i < 8; ++i) {
        cv::Mat version = t.clone();
        if (i % 4 != 0) cv::rotate(t, version, i % 4 == 1 ? cv::ROTATE_90_CLOCKWISE : i % 4 == 2 ? cv::ROTATE_180
                                                                                                : cv::ROTATE_90_COUNTERCLOCKWISE);
        if (i >= 4) cv::flip(version, version, 1);
        version.copyTo(composite(cv::Rect((i % 4) * t.cols, (i / 4) * t.rows, t.cols, t.rows)));
      }
      floor_options.image = scratch_ / "floor.pgm";
      ASSERT_TRUE(cv::imwrite(floor_options.image.string(), composite));
    }
    if (!floor_) floor_ = sim::MakeImageFloor(floor_options);
    mosaic::MapGrid grid;  // 0.25 mm/px, origin (0, 0), 256 px tiles
    store_ = mosaic::TileStore::Create(scratch_ / "floor.mosaic", grid);
    std::vector<mosaic::TileWrite> tiles;
    for (int row = 0; row < MapRows(); ++row) {    // y from 0 down (-384 mm for 6 rows)
      for (int col = 0; col < MapCols(); ++col) {  // x from 0 (to 896 mm for 14 columns)
        if (!Mapped(col)) continue;
        const cv::Point2i shift = PaintedShift(col);
        cv::Mat texels = floor_->Render(2 * 256 * col + shift.x, 2 * 256 * row + shift.y, 512, 512), pixels;
        cv::resize(texels, pixels, cv::Size(256, 256), 0, 0, cv::INTER_AREA);
        cv::max(pixels, 1, pixels);
        tiles.push_back({mosaic::TileKey{0, col, row}, pixels});
      }
    }
    mosaic::WriteWithPyramid(*store_, tiles);
    cache_ = std::make_unique<mosaic::TileCache>(*store_);
    renderer_ = std::make_unique<mosaic::MapRenderer>(*cache_);
    reference_ = std::make_unique<tracking::MapReference>(*renderer_, 0);
  }

  // Truth: an arc of 3 m radius at `speed_mps` (a path a differential drive can follow),
  // starting at x = 150 mm heading slightly right.
  static Pose2 Truth(double t_s, double speed_mps) {
    const double travel_mm = speed_mps * 1000.0 * t_s;
    return Pose2(150.0, -180.0, -0.06) * Pose2::Exp({travel_mm, 0.0, travel_mm / 3000.0});
  }

  struct Run {
    std::vector<double> errors_mm;
    int fixes = 0;
    std::int64_t lock_losses = 0;
    std::vector<std::string> reasons;  ///< the first frames without a fix, why
    int first_fix_frame = -1;
    std::vector<double> fix_errors_mm;  ///< per frame: the accepted fix's error, -1 without one
    std::vector<estimation::LockState> states;
    std::vector<Mode> modes;
    std::vector<double> sigmas_mm;  ///< per frame: the estimate's position standard deviation
    std::vector<double> yaw_errors_deg;  ///< per frame: the estimate's heading error
    std::vector<double> yaw_sigmas_deg;  ///< and its standard deviation
    std::vector<Pose2> cameras;  ///< the true camera pose of each frame
    std::vector<int> inliers;    ///< per frame: the templates the accepted fix rests on, 0 without one
    std::int64_t relocalizations = 0;
    std::int64_t reanchorings = 0;
    int misses = 0;  ///< frames without a fix
    int rejected = 0;  ///< frames whose fix the filter's gate refused
    std::string first_rejection;  ///< the first of those, why
    estimation::LockState last_state = estimation::LockState::kTracking;
    std::vector<std::string> words;  ///< ReasonWord() of the first frames without a fix
    int registered_to_frame_before = 0;  ///< visual odometry's links to the frame before, not the keyframe
  };

  // Runs the localizer for `seconds`, encoders at 100 Hz with a 2 % scale error, frames at
  // 30 Hz; starts from `start_error` off the truth.
  // `slip_mm`: from 0.5 s on, both wheels count that much more travel than was driven (a
  // wheel slip the odometry model does not expect).
  Run Localize(double seconds, double speed_mps, const Pose2& start_error, double start_sigma_mm = 1.0,
               double slip_mm = 0.0, int reanchor_after = LocalizerOptions{}.reanchor_after_rejections,
               bool relocalize = false) {
    const camera::IdealCamera camera{camera::IdealCameraOptions{}};
    sim::ImagingOptions imaging;
    const sim::Imager imager(*floor_, camera, imaging, 7);
    // A body that rolls in the turn (body_roll_deg_per_mps2_) about an axis body_pivot_mm_
    // over the floor: the view tilts, and its centre moves that height times the roll aside
    // from the mounting point.
    std::optional<sim::CameraPlacement> placement;
    if (body_roll_deg_per_mps2_ != 0.0) {
      sim::CameraPlacementOptions rolling;
      rolling.vehicle_from_camera = Pose2(200.0, 0.0, 0.0);  // as below
      rolling.suspension.roll_deg_per_mps2 = body_roll_deg_per_mps2_;
      rolling.suspension.pivot_height_mm = body_pivot_mm_;
      placement.emplace(rolling, camera.mm_per_px(), camera.cx(), camera.cy());
    }
    LocalizerOptions options = options_;
    options.vehicle_from_camera = Pose2(200.0, 0.0, 0.0);
    options.reanchor_after_rejections = reanchor_after;
    // With a place index, the whole map can be searched (an unknown start).
    std::unique_ptr<tracking::PlaceIndex> places;
    if (unknown_start_ || index_map_) {
      store_->WritePlaces(tracking::PlaceIndexInfoFor(place_index_), tracking::BuildPlaceCells(*store_, place_index_));
      if (floor_repeats_) store_->WritePlaceRepeatTest(24, 0, 24);  // the self-test's verdict, as map build stores it
      places = std::make_unique<tracking::PlaceIndex>(*store_, place_index_);
    }
    Localizer localizer(camera, options, *reference_, places.get());
    const double b = options.odometry.wheels.track_width_mm;
    const double mm_per_tick = 2.0 * std::numbers::pi * options.odometry.wheels.left_wheel_radius_mm /
                               static_cast<double>(options.odometry.wheels.ticks_per_revolution);
    double left_mm = 0.0, right_mm = 0.0;
    const auto ticks = [mm_per_tick](double mm) { return static_cast<std::int32_t>(std::lround(mm / mm_per_tick)); };
    localizer.Initialize(Timestamp(), Truth(0.0, speed_mps) * start_error,
                         Eigen::Vector3d(start_sigma_mm * start_sigma_mm, start_sigma_mm * start_sigma_mm, 1e-4)
                             .asDiagonal());
    if (unknown_start_) localizer.InitializeUnknown(Timestamp());
    localizer.AddEncoders(Timestamp(), core::EncoderCounts{});
    if (relocalize) localizer.RequestRelocalization();
    Run run;
    int encoder_step = 0;
    for (int frame = 1; frame < static_cast<int>(seconds * 30.0); ++frame) {
      const double t_frame = frame / 30.0;
      // Odometry up to the first sample after the frame (the fix comes late, as live).
      while (encoder_step / 100.0 <= t_frame) {
        ++encoder_step;
        const Eigen::Vector3d twist =
            Between(Truth((encoder_step - 1) / 100.0, speed_mps), Truth(encoder_step / 100.0, speed_mps)).Log();
        left_mm += 1.02 * (twist.x() - 0.5 * b * twist.z());
        right_mm += 1.02 * (twist.x() + 0.5 * b * twist.z());
        const double slip = encoder_step >= 50 ? slip_mm : 0.0;
        localizer.AddEncoders(Timestamp::FromSeconds(encoder_step / 100.0),
                              core::EncoderCounts{ticks(left_mm + slip), ticks(right_mm + slip)});
      }
      const Pose2 truth = Truth(t_frame, speed_mps);
      const Pose2 camera_pose = truth * options.vehicle_from_camera;
      cv::Mat image;
      if (placement) {
        // On the arc of 3 m radius: (longitudinal, lateral) acceleration 0 and v² / r.
        const sim::CameraView view = placement->At(truth, Eigen::Vector2d(0.0, speed_mps * speed_mps / 3.0), t_frame);
        image = imager.Render([&](const Eigen::Vector2d& px) { return placement->PixelToWorld(view, px); },
                              Eigen::Vector2d(speed_mps * 1000.0, 0.0), t_frame, static_cast<std::uint64_t>(frame));
      } else {
        image = imager.Render(camera_pose, Eigen::Vector2d(speed_mps * 1000.0, 0.0), t_frame,
                              static_cast<std::uint64_t>(frame));
      }
      const FrameOutcome outcome = localizer.ProcessFrame(Timestamp::FromSeconds(t_frame), image);
      run.fixes += outcome.fixed ? 1 : 0;
      if (outcome.reason.find("registered to the frame before") != std::string::npos) ++run.registered_to_frame_before;
      if (outcome.fixed && run.first_fix_frame < 0) run.first_fix_frame = frame;
      run.last_state = outcome.lock;
      run.states.push_back(outcome.lock);
      run.modes.push_back(outcome.mode);
      run.sigmas_mm.push_back(std::sqrt(std::max(outcome.covariance(0, 0), outcome.covariance(1, 1))));
      run.cameras.push_back(camera_pose);
      run.inliers.push_back(outcome.fixed ? outcome.track.inliers : 0);
      run.fix_errors_mm.push_back(outcome.fixed ? Distance(outcome.fix_world_from_vehicle, truth) : -1.0);
      if (!outcome.fixed && run.words.size() < 5) run.words.push_back(outcome.ReasonWord());
      if (!outcome.fixed && outcome.ReasonWord() == "rejected" && run.rejected++ == 0) {
        run.first_rejection = outcome.reason;
      }
      if (!outcome.fixed && run.reasons.size() < 5) {
        const Pose2& found = outcome.track.world_from_camera;
        run.reasons.push_back(outcome.reason + " (camera found at " + std::to_string(found.x_mm()) + ", " +
                              std::to_string(found.y_mm()) + ", " + std::to_string(found.yaw_rad()) + ", truth " +
                              std::to_string(camera_pose.x_mm()) + ", " + std::to_string(camera_pose.y_mm()) + ", " +
                              std::to_string(camera_pose.yaw_rad()) + "; vehicle predicted " +
                              std::to_string(outcome.world_from_vehicle.x_mm()) + ", " +
                              std::to_string(outcome.world_from_vehicle.y_mm()) + ", " +
                              std::to_string(outcome.world_from_vehicle.yaw_rad()) + " truth " +
                              std::to_string(truth.x_mm()) + ", " + std::to_string(truth.y_mm()) + ", " +
                              std::to_string(truth.yaw_rad()) + " sigma " +
                              std::to_string(std::sqrt(outcome.covariance(0, 0))) + ")");
      }
      run.errors_mm.push_back(Distance(outcome.world_from_vehicle, truth));
      run.yaw_errors_deg.push_back(core::WrapAngle(outcome.world_from_vehicle.yaw_rad() - truth.yaw_rad()) * 180.0 /
                                   std::numbers::pi);
      run.yaw_sigmas_deg.push_back(std::sqrt(outcome.covariance(2, 2)) * 180.0 / std::numbers::pi);
    }
    run.lock_losses = localizer.lock().losses();
    run.misses = static_cast<int>(run.errors_mm.size()) - run.fixes;
    run.relocalizations = localizer.relocalizations();
    run.reanchorings = localizer.reanchorings();
    return run;
  }

  /// Without a start pose, the first frame is found on the whole map and every fix after it is right.
  void ExpectAnUnknownStartFound() {
    unknown_start_ = true;
    const Run run = Localize(1.0, 0.3, Pose2());
    ASSERT_FALSE(run.errors_mm.empty());
    EXPECT_EQ(run.first_fix_frame, 1) << (run.reasons.empty() ? std::string() : run.reasons.front());
    EXPECT_EQ(run.fixes, static_cast<int>(run.errors_mm.size()));
    EXPECT_EQ(run.lock_losses, 0);
    for (const double e : run.fix_errors_mm) EXPECT_LT(e, 0.2);
  }

  LocalizerOptions options_;  ///< what Localize starts from (tests may change it first)
  bool unknown_start_ = false;  ///< Localize indexes the map and starts without a pose
  tracking::PlaceIndexOptions place_index_;  ///< that index's options
  bool floor_repeats_ = false;  ///< the index records the floor's self-test as finding copies
  bool index_map_ = false;  ///< Localize indexes the map (as with unknown_start_) but starts with a pose
  double body_roll_deg_per_mps2_ = 0.0;  ///< the simulated body's roll out of the turn
  double body_pivot_mm_ = 0.0;  ///< and the height over the floor of the axis it rolls about
  test::ScratchDir scratch_;
  std::unique_ptr<sim::Floor> floor_;
  std::unique_ptr<mosaic::TileStore> store_;
  std::unique_ptr<mosaic::TileCache> cache_;
  std::unique_ptr<mosaic::MapRenderer> renderer_;
  std::unique_ptr<tracking::MapReference> reference_;
};

TEST_F(Drive, TracksToAFractionOfAMillimetreWithBiasedOdometry) {
  const Run run = Localize(1.5, 0.3, Pose2());
  ASSERT_FALSE(run.errors_mm.empty());
  double sum_sq = 0.0, max = 0.0;
  for (const double e : run.errors_mm) {
    sum_sq += e * e;
    max = std::max(max, e);
  }
  const double rms = std::sqrt(sum_sq / static_cast<double>(run.errors_mm.size()));
  RecordProperty("position_rms_mm", std::to_string(rms));
  EXPECT_EQ(run.lock_losses, 0);
  EXPECT_EQ(run.fixes, static_cast<int>(run.errors_mm.size()))
      << (run.reasons.empty() ? std::string() : run.reasons.front());
  EXPECT_LT(rms, 0.05);
  EXPECT_LT(max, 0.2);
}

// Creeping at 1 mm/s (docking): the encoders tick every 0.115 mm, so for three or four frames
// at a time the wheels say the vehicle stands while it has moved up to a tick. The fixes see
// every micrometre of it; a filter that took "no tick" for "no motion" would refuse them.
TEST_F(Drive, ACreepingVehicleKeepsItsFixesBetweenEncoderTicks) {
  const Run run = Localize(1.5, 0.001, Pose2());
  ASSERT_FALSE(run.errors_mm.empty());
  EXPECT_EQ(run.rejected, 0) << run.first_rejection;
  EXPECT_EQ(run.fixes, static_cast<int>(run.errors_mm.size()))
      << (run.reasons.empty() ? std::string() : run.reasons.front());
  EXPECT_EQ(run.lock_losses, 0);
  EXPECT_LT(*std::max_element(run.errors_mm.begin(), run.errors_mm.end()), 0.02);
}

class ProceduralDrive : public Drive {
 protected:
  bool Procedural() const override { return true; }
};

// No start pose at all: the first frame is looked up on the whole map through its place index
// and verified, and tracking goes on from there.
TEST_F(ProceduralDrive, AnUnknownStartIsFoundOnTheWholeMap) { ExpectAnUnknownStartFound(); }

class PatchedAsphaltDrive : public Drive {
 protected:
  bool Patches() const override { return true; }
};

// The same on real asphalt that does not repeat: each view holds several patches of the picture,
// each also found elsewhere on the map, but only the true place holds them all as they lie.
TEST_F(PatchedAsphaltDrive, AnUnknownStartIsFoundOnTheWholeMap) { ExpectAnUnknownStartFound(); }

TEST_F(Drive, OffTheMapIsOffMapNotLost) {
  // Start 2 m away from the mapped strip: no fix can be made, and none is expected there. The
  // localizer dead-reckons, says off-map, and neither loses the lock nor searches the map.
  const Run run = Localize(1.0, 0.3, Pose2(0.0, 2000.0, 0.0));
  EXPECT_EQ(run.fixes, 0);
  EXPECT_EQ(run.lock_losses, 0);
  EXPECT_EQ(run.relocalizations, 0);
  EXPECT_EQ(run.last_state, estimation::LockState::kOffMap);
  ASSERT_FALSE(run.reasons.empty());
  EXPECT_EQ(run.reasons.front().rfind("off-map: 0 % of the predicted view is mapped", 0), 0u) << run.reasons.front();
  EXPECT_EQ(run.words.front(), "off-map");
}

TEST_F(Drive, KidnappedStartRelocalizesWithinTenFrames) {
  // The start is given half a metre off, with an uncertainty that says so.
  const Run run = Localize(1.0, 0.3, Pose2(500.0, 0.0, 0.0), 250.0);
  ASSERT_GE(run.first_fix_frame, 1) << (run.reasons.empty() ? std::string() : run.reasons.front());
  RecordProperty("first_fix_frame", run.first_fix_frame);
  EXPECT_LE(run.first_fix_frame, 10);
  EXPECT_GE(run.relocalizations, 1);
  EXPECT_LT(run.errors_mm.back(), 0.05) << "after relocalizing, it tracks";
}

// A start a quarter of a metre off that claims to be good to a millimetre (a vehicle pushed
// aside while switched off): the tracker's small window misses where the prediction, with its
// uncertainty, lies wholly on the map. That is evidence of a kidnap: after a few such frames
// the map is searched without the prior, before the lock is lost.
TEST_F(Drive, KidnappedStartWithAConfidentPriorRelocalizesWithinTenFrames) {
  const Run run = Localize(1.0, 0.3, Pose2(-250.0, 0.0, 0.0));
  ASSERT_GE(run.first_fix_frame, 1) << (run.reasons.empty() ? std::string() : run.reasons.front());
  RecordProperty("first_fix_frame", run.first_fix_frame);
  EXPECT_LE(run.first_fix_frame, 10);
  EXPECT_EQ(run.lock_losses, 0);
  EXPECT_EQ(run.relocalizations, 1);
  EXPECT_EQ(run.words.front(), "no-match") << "a miss on the map, not off it";
  // From the relocalization on (frame f is errors_mm[f - 1]) it is where it is.
  for (std::size_t i = static_cast<std::size_t>(run.first_fix_frame) - 1; i < run.errors_mm.size(); ++i) {
    EXPECT_LT(run.errors_mm[i], 0.1) << "frame " << i + 1;
  }
  EXPECT_LT(run.errors_mm.back(), 0.05);
}

// A start 100 mm off that claims 20 mm: the place the search finds lies five sigmas from the
// prediction, outside its gate, and is not taken however well it matches. The misses where the
// view must be on the map are then evidence of a kidnap, and after five of them the search
// without the prior takes the place.
TEST_F(Drive, PlaceOutsideThePriorsGateIsTakenOnlyOnEvidenceOfAKidnap) {
  const Run run = Localize(1.0, 0.3, Pose2(100.0, 0.0, 0.0), 20.0);
  ASSERT_GE(run.first_fix_frame, 1) << (run.reasons.empty() ? std::string() : run.reasons.front());
  EXPECT_GE(run.first_fix_frame, 6) << "a place outside the gate was taken before the evidence";
  EXPECT_LE(run.first_fix_frame, 10);
  ASSERT_FALSE(run.reasons.empty());
  EXPECT_NE(run.reasons.front().find("none within the prediction's uncertainty"), std::string::npos)
      << run.reasons.front();
  EXPECT_EQ(run.relocalizations, 1);
  for (std::size_t i = 0; i < run.fix_errors_mm.size(); ++i) EXPECT_LT(run.fix_errors_mm[i], 0.1) << "frame " << i + 1;
}

// The same start off the map, but known to be untrustworthy (the vehicle was moved): the
// request drops the prior at once, and the first frame is fixed where the vehicle is.
TEST_F(Drive, RequestedRelocalizationIgnoresTheConfidentPrior) {
  const Run without = Localize(0.5, 0.3, Pose2(0.0, 300.0, 0.0));
  EXPECT_EQ(without.fixes, 0) << "the prior puts the view off the map: nothing to search for";
  const Run run = Localize(0.5, 0.3, Pose2(0.0, 300.0, 0.0), 1.0, 0.0, LocalizerOptions{}.reanchor_after_rejections,
                           /*relocalize=*/true);
  EXPECT_EQ(run.first_fix_frame, 1) << (run.reasons.empty() ? std::string() : run.reasons.front());
  EXPECT_EQ(run.relocalizations, 1);
  EXPECT_LT(run.errors_mm.back(), 0.05);
}

TEST_F(Drive, MapCoverageIsTheShareOfTheViewOnTheMap) {
  const camera::IdealCamera camera{camera::IdealCameraOptions{}};  // 160 x 120 mm
  // The map covers x 0..896, y -384..0.
  EXPECT_DOUBLE_EQ(MapCoverage(*reference_, camera, Pose2(400.0, -200.0, 0.0), 0.0, 2), 1.0);
  EXPECT_NEAR(MapCoverage(*reference_, camera, Pose2(896.0, -200.0, 0.0), 0.0, 2), 0.5, 0.03) << "half over the end";
  EXPECT_NEAR(MapCoverage(*reference_, camera, Pose2(896.0, -200.0, 0.0), 0.0, 0), 0.5, 0.01) << "level 0";
  EXPECT_DOUBLE_EQ(MapCoverage(*reference_, camera, Pose2(400.0, 2000.0, 0.3), 0.0, 2), 0.0);
  // Grown by 100 mm on every side the region (y -280..40) reaches 40 mm past y = 0: 280 of 320 mm mapped.
  EXPECT_NEAR(MapCoverage(*reference_, camera, Pose2(400.0, -120.0, 0.0), 100.0, 2), 280.0 / 320.0, 0.03);
  // Turned a quarter, the view is 120 mm wide along x: 60 mm past the end is half of it.
  EXPECT_NEAR(MapCoverage(*reference_, camera, Pose2(896.0, -200.0, 0.5 * std::numbers::pi), 0.0, 2), 0.5, 0.03);
}

// A 3 mm slip puts the odometry off by far more than the filter believes: every fix is
// rejected at the gate, each off the prediction by the same 3 mm. The filter restarts from
// them after three, instead of losing the lock half a second later.
TEST_F(Drive, ConsistentlyRejectedFixesReanchorTheFilter) {
  const Run run = Localize(1.2, 0.3, Pose2(), 1.0, 3.0);
  EXPECT_EQ(run.lock_losses, 0);
  EXPECT_EQ(run.reanchorings, 1);
  EXPECT_EQ(run.relocalizations, 0);  // no search: the fixes were there all along
  EXPECT_LE(run.misses, 2) << (run.reasons.empty() ? std::string() : run.reasons.back());
  EXPECT_LT(run.errors_mm.back(), 0.05);
  // Without it the fixes stay rejected until the prediction's uncertainty, growing frame by
  // frame without a fix, covers the slip.
  const Run without = Localize(1.2, 0.3, Pose2(), 1.0, 3.0, 0);
  EXPECT_GE(without.misses, 5);
}

// The plain texture, repeating every 256 mm: a start given half a period off, between two
// copies of the floor, must not relocalize onto either.
class RepeatingDrive : public Drive {
 protected:
  bool Repeating() const override { return true; }
  // A start without a pose that never found one: every frame ambiguous, no fix, still searching.
  static void ExpectSearchingAmbiguous(const Run& run) {
    ASSERT_FALSE(run.errors_mm.empty());
    EXPECT_EQ(run.fixes, 0);
    for (const double e : run.fix_errors_mm) EXPECT_LT(e, 1.0);
    ASSERT_FALSE(run.words.empty());
    EXPECT_EQ(run.words.front(), "ambiguous") << run.reasons.front();
    EXPECT_EQ(run.last_state, estimation::LockState::kSearching);
  }
};

TEST_F(RepeatingDrive, StartBetweenTwoCopiesOfTheFloorIsAmbiguousNotAWrongFix) {
  const Run run = Localize(0.5, 0.3, Pose2(128.0, 0.0, 0.0), 250.0);
  EXPECT_EQ(run.fixes, 0) << "a copy of the floor taken for the place";
  EXPECT_EQ(run.relocalizations, 0);
  ASSERT_FALSE(run.reasons.empty());
  EXPECT_NE(run.reasons.front().find("places match the frame equally well"), std::string::npos)
      << run.reasons.front();
}

// The same start claiming a millimetre: the wide search after the first misses finds the two
// copies equally good too, and takes neither.
TEST_F(RepeatingDrive, ConfidentStartBetweenTwoCopiesIsNeverAWrongFix) {
  const Run run = Localize(0.5, 0.3, Pose2(128.0, 0.0, 0.0));
  EXPECT_EQ(run.fixes, 0) << "a copy of the floor taken for the place";
  EXPECT_EQ(run.relocalizations, 0);
}

TEST_F(RepeatingDrive, StartNearOneCopyRelocalizesOntoIt) {
  // 40 mm off: the nearest copy is the true place, the next over 200 mm away.
  const Run run = Localize(0.5, 0.3, Pose2(40.0, 0.0, 0.0), 250.0);
  ASSERT_GE(run.first_fix_frame, 1) << (run.reasons.empty() ? std::string() : run.reasons.front());
  EXPECT_GE(run.relocalizations, 1);
  EXPECT_LT(run.errors_mm.back(), 0.05);
}

// The same 40 mm off with a prior of 100 mm on a map whose self-test found the floor repeats:
// the copies 216 and 296 mm away lie inside the prediction's gate too. The true place is the
// nearest, but a prediction wrong by more than it says would put a copy nearest just the same
// (a vehicle carried unseen): two places inside the gate on such a floor are ambiguous.
TEST_F(RepeatingDrive, TwoCopiesInsideTheGateOfAFloorKnownToRepeatAreAmbiguous) {
  index_map_ = true;
  floor_repeats_ = true;
  const Run run = Localize(0.5, 0.3, Pose2(40.0, 0.0, 0.0), 100.0);
  ASSERT_FALSE(run.errors_mm.empty());
  EXPECT_EQ(run.fixes, 0) << "a place taken where copies of the floor lie inside the gate";
  for (const double e : run.fix_errors_mm) EXPECT_LT(e, 1.0);
  ASSERT_FALSE(run.reasons.empty());
  EXPECT_NE(run.reasons.front().find("inside the prediction's uncertainty and the floor repeats"), std::string::npos)
      << run.reasons.front();
}

// No start pose over a floor that repeats: every frame matches several places on the map, so
// the search says "ambiguous" and gives no fix; never one on a copy.
TEST_F(RepeatingDrive, AnUnknownStartIsAmbiguousNeverWrong) {
  unknown_start_ = true;
  const Run run = Localize(0.5, 0.3, Pose2());
  ExpectSearchingAmbiguous(run);
  EXPECT_EQ(run.lock_losses, 0);
}

// The index proposes a few of the places a frame's corners vote for (max_candidates), not every
// copy of a floor that repeats: where the self-test found copies, the one place that verifies
// among them may be a copy of the true place, which was never tried, and is no fix. With one
// candidate proposed, every search verifies at most one place.
TEST_F(RepeatingDrive, OnePlaceVerifiedOnAFloorThatRepeatsIsNoFix) {
  unknown_start_ = true;
  place_index_.max_candidates = 1;
  floor_repeats_ = true;
  const Run run = Localize(0.5, 0.3, Pose2());
  ExpectSearchingAmbiguous(run);
  if (HasFatalFailure()) return;
  EXPECT_NE(run.reasons.front().find("proposes only some of its copies"), std::string::npos) << run.reasons.front();
}

// The repeating floor with a 512 mm band across the lane left unmapped (x 448 to 960 mm): a
// vehicle leaves the map and comes back onto it, as on a lane nobody mapped yet. In the band
// the nearest mapped copies of its view lie one and two periods behind it.
class RepeatingExcursion : public Drive {
 protected:
  bool Repeating() const override { return true; }
  int MapCols() const override { return 20; }
  int MapRows() const override { return 8; }
  bool Mapped(int col) const override { return col < 7 || col > 14; }
};

TEST_F(RepeatingExcursion, LeavingTheMapIsOffMapAndNeverAWrongFix) {
  const Run run = Localize(1.6, 0.5, Pose2());
  ASSERT_FALSE(run.errors_mm.empty());
  int wrong = 0, off_map = 0;
  for (std::size_t i = 0; i < run.fix_errors_mm.size(); ++i) {
    if (run.fix_errors_mm[i] > 1.0) {
      ++wrong;
      ADD_FAILURE() << "frame " << i + 1 << ": a fix " << run.fix_errors_mm[i] << " mm off";
    }
    off_map += run.states[i] == estimation::LockState::kOffMap ? 1 : 0;
  }
  EXPECT_EQ(wrong, 0);
  EXPECT_GE(off_map, 5) << "the view wholly in the band is off the map";
  EXPECT_EQ(run.lock_losses, 0) << "off the map is not lost";
  // Back on the map (the whole view past x = 960 mm): a fix within three frames, on the truth.
  std::size_t back = 0;
  while (back < run.cameras.size() && run.cameras[back].x_mm() - 80.0 < 960.0) ++back;
  ASSERT_LT(back + 3, run.cameras.size());
  std::size_t first = back;
  while (first < back + 3 && run.fix_errors_mm[first] < 0.0) ++first;
  ASSERT_LT(first, back + 3) << "no fix within three frames of the return";
  EXPECT_LT(run.fix_errors_mm[first], 0.02);
  EXPECT_LT(run.errors_mm.back(), 0.05);
}

// Off the map, each frame is registered against the keyframe and the estimate chained on:
// it holds far better than the wheels (2 % off, while the filter is still learning by how
// much), its uncertainty grows frame by frame, and it never makes a fix. Back on the map the
// first fix is on the truth.
TEST_F(RepeatingExcursion, OffTheMapVisualOdometryHoldsThePoseWhereTheWheelsDrift) {
  const auto off_map_worst = [](const Run& run, Mode mode, int* frames) {
    double worst = 0.0;
    *frames = 0;
    for (std::size_t i = 0; i < run.errors_mm.size(); ++i) {
      if (run.states[i] != estimation::LockState::kOffMap) continue;
      worst = std::max(worst, run.errors_mm[i]);
      *frames += run.modes[i] == mode ? 1 : 0;
    }
    return worst;
  };
  options_.visual_odometry.enabled = false;
  const Run wheels = Localize(1.6, 0.5, Pose2(), 1.0, /*slip_mm=*/0.0);
  options_.visual_odometry.enabled = true;
  const Run vo = Localize(1.6, 0.5, Pose2(), 1.0, 0.0);
  int dead_reckoned = 0, registered = 0;
  const double wheels_worst = off_map_worst(wheels, Mode::kDeadReckoning, &dead_reckoned);
  const double vo_worst = off_map_worst(vo, Mode::kVisualOdometry, &registered);
  RecordProperty("off_map_worst_error_um_wheels", static_cast<int>(1000.0 * wheels_worst));
  RecordProperty("off_map_worst_error_um_visual_odometry", static_cast<int>(1000.0 * vo_worst));
  EXPECT_GE(dead_reckoned, 5);
  EXPECT_GE(registered, 5) << "off the map, frames are registered frame to keyframe";
  EXPECT_LT(vo_worst, 0.1) << "the wheels alone: " << wheels_worst << " mm";
  EXPECT_LT(vo_worst, 0.5 * wheels_worst);
  // The uncertainty grows while off the map, and no frame there counts as a fix.
  double first_sigma = -1.0, last_sigma = -1.0;
  for (std::size_t i = 0; i < vo.modes.size(); ++i) {
    if (vo.modes[i] != Mode::kVisualOdometry) continue;
    EXPECT_LT(vo.fix_errors_mm[i], 0.0) << "frame " << i + 1 << " off the map counted as a fix";
    if (first_sigma < 0.0) first_sigma = vo.sigmas_mm[i];
    last_sigma = vo.sigmas_mm[i];
  }
  EXPECT_GT(last_sigma, first_sigma);
  for (const double e : vo.fix_errors_mm) EXPECT_LT(e, 1.0) << "a wrong fix";
  EXPECT_EQ(vo.lock_losses, 0);
  EXPECT_LT(vo.errors_mm.back(), 0.05);
  EXPECT_EQ(vo.modes.back(), Mode::kTrack);
}

// Keyframes kept until the view has moved 0.9 of its shorter side, at 1.45 m/s (0.4 of it a
// frame): the second frame after a keyframe has moved 0.8 from it, too few templates fall on
// it, and it is registered against the frame before instead, 0.4 away. The chain goes on
// unbroken: no frame off the map is dead-reckoned (without the frame before, six were, and
// the estimate came back onto the map 1.0 mm off).
TEST_F(RepeatingExcursion, AFrameTheKeyframeDoesNotRegisterIsRegisteredToTheFrameBefore) {
  options_.visual_odometry.keyframe_fraction = 0.9;
  options_.visual_odometry.max_fraction = 0.9;
  const Run run = Localize(0.9, 1.45, Pose2());
  ASSERT_FALSE(run.errors_mm.empty());
  EXPECT_GE(std::count(run.modes.begin(), run.modes.end(), Mode::kVisualOdometry), 4);
  EXPECT_GE(run.registered_to_frame_before, 1);
  EXPECT_EQ(std::count(run.modes.begin(), run.modes.end(), Mode::kDeadReckoning), 0);
  EXPECT_EQ(run.lock_losses, 0);
  for (const double e : run.fix_errors_mm) EXPECT_LT(e, 1.0) << "a wrong fix";
  double worst = 0.0;
  for (std::size_t i = 0; i < run.errors_mm.size(); ++i) {
    if (run.modes[i] == Mode::kVisualOdometry) worst = std::max(worst, run.errors_mm[i]);
  }
  EXPECT_LT(worst, 0.1);
}

// Coming back onto the map the view is half off it and its templates all lie on one side; the
// place found is registered again with 16 templates, so the first fix rests on more of them
// than the four a frame is registered with otherwise.
TEST_F(RepeatingExcursion, AViewPartlyOffTheMapIsRegisteredAgainWithMoreTemplates) {
  const auto first_fix_back = [](const Run& run) {
    std::size_t i = 0;
    while (i < run.cameras.size() && run.cameras[i].x_mm() + 80.0 < 960.0) ++i;  // still wholly in the band
    while (i < run.inliers.size() && run.inliers[i] == 0) ++i;
    return i;
  };
  options_.edge_templates = 0;
  const Run four = Localize(1.6, 0.5, Pose2());
  options_.edge_templates = 16;
  const Run sixteen = Localize(1.6, 0.5, Pose2());
  const std::size_t a = first_fix_back(four), b = first_fix_back(sixteen);
  ASSERT_LT(a, four.inliers.size());
  ASSERT_LT(b, sixteen.inliers.size());
  EXPECT_LE(four.inliers[a], 4);
  EXPECT_GT(sixteen.inliers[b], 4);
  EXPECT_LT(sixteen.fix_errors_mm[b], 0.02);
}

// A map that is not rigid, as one built from a mapping drive that closed no loop between two
// lanes: the lane beyond the unmapped band is painted 1.5 mm to the side of where it lies. Off
// the map, visual odometry follows the true motion; back on it, the map's own error there is
// not the one where the vehicle left it. The prediction carries the map's distortion over the
// path driven off it (map_distortion_mm_per_m), so the first view back on the map is fixed,
// in the map's frame there.
class DistortedExcursion : public Drive {
 protected:
  int MapCols() const override { return 20; }
  int MapRows() const override { return 8; }
  bool Mapped(int col) const override { return col < 7 || col > 14; }
  cv::Point2i PaintedShift(int col) const override { return {0, col > 14 ? 12 : 0}; }  // 12 x 0.125 mm
};

TEST_F(DistortedExcursion, TheMapsDistortionOverTheExcursionIsInTheGate) {
  const auto back_on_the_map = [](const Run& run) {
    std::size_t i = 0;
    while (i < run.cameras.size() && run.cameras[i].x_mm() - 80.0 < 960.0) ++i;  // the whole view past the band
    return i;
  };
  options_.map_distortion_mm_per_m = 0.0;
  const Run rigid = Localize(1.6, 0.5, Pose2());
  options_.map_distortion_mm_per_m = LocalizerOptions{}.map_distortion_mm_per_m;
  const Run widened = Localize(1.6, 0.5, Pose2());
  for (const Run* run : {&rigid, &widened}) {
    const std::size_t back = back_on_the_map(*run);
    ASSERT_LT(back + 5, run->fix_errors_mm.size());
    EXPECT_EQ(run->lock_losses, 0);
    // After the return every fix is the map's, 1.5 mm to the side of the truth.
    for (std::size_t i = back + 5; i < run->fix_errors_mm.size(); ++i) {
      if (run->fix_errors_mm[i] >= 0.0) {
        EXPECT_NEAR(run->fix_errors_mm[i], 1.5, 0.05) << "frame " << i + 1;
      }
    }
  }
  EXPECT_GE(rigid.rejected, 1) << "a rigid map's prediction refuses the map's own error";
  EXPECT_EQ(widened.rejected, 0) << widened.first_rejection;
  RecordProperty("first_rejection_without_the_distortion", rigid.first_rejection);
  const std::size_t back = back_on_the_map(widened);
  EXPECT_GE(widened.fix_errors_mm[back], 0.0) << "the first view wholly back on the map is fixed";
}

// A body leaning 0.67° out of a turn about an axis 100 mm over the floor puts the image centre
// 1.2 mm beside the mounting point. Where the templates measure the tilt, the fix takes that
// lever out; where they are too few (here never: min_tilt_points above the templates' count, as
// at the edge of the map), the lever is only known to the body's tilt_sigma_deg, and a fix that
// uncertain is not taken: taken, it would be a millimetre off.
TEST_F(Drive, AFixTooSparseToMeasureTheTiltItsLeverDependsOnIsNotTaken) {
  body_roll_deg_per_mps2_ = 8.0;  // 0.5 m/s on the 3 m arc: 0.083 m/s², 0.67°
  body_pivot_mm_ = 100.0;
  options_.tracker.templates.count = 12;
  options_.tracker.solver.estimate_tilt = true;
  options_.tilt_pivot_height_mm = 100.0;
  const auto drive = [&](int min_tilt_points, double max_fixed_sigma_mm) {
    options_.tracker.solver.min_tilt_points = min_tilt_points;
    options_.max_fixed_sigma_mm = max_fixed_sigma_mm;
    return Localize(1.0, 0.5, Pose2());
  };
  const double bound = LocalizerOptions{}.max_fixed_sigma_mm;
  const Run measured = drive(8, bound);
  const Run unmeasured = drive(64, bound);
  const Run unbounded = drive(64, 100.0);
  ASSERT_FALSE(measured.errors_mm.empty());
  EXPECT_EQ(measured.fixes, static_cast<int>(measured.errors_mm.size()))
      << (measured.reasons.empty() ? std::string() : measured.reasons.front());
  for (const double e : measured.fix_errors_mm) EXPECT_LT(e, 0.1);
  EXPECT_EQ(unmeasured.fixes, 0);
  ASSERT_FALSE(unmeasured.reasons.empty());
  EXPECT_NE(unmeasured.reasons.front().find("too uncertain"), std::string::npos) << unmeasured.reasons.front();
  EXPECT_NE(unmeasured.reasons.front().find("too few to measure the tilt"), std::string::npos);
  EXPECT_EQ(unmeasured.words.front(), "rejected");
  // What the bound keeps out: the same fixes taken are as far off as the lever.
  ASSERT_GT(unbounded.fixes, 10);
  const double taken_max_mm = *std::max_element(unbounded.fix_errors_mm.begin(), unbounded.fix_errors_mm.end());
  RecordProperty("fix_error_max_mm_tilt_measured",
                 std::to_string(*std::max_element(measured.fix_errors_mm.begin(), measured.fix_errors_mm.end())));
  RecordProperty("fix_error_max_mm_tilt_unmeasured_taken", std::to_string(taken_max_mm));
  EXPECT_GT(taken_max_mm, 0.8);
}

TEST(CovarianceTransfer, CameraAndVehicleCovariancesAreInverse) {
  const Pose2 world_from_vehicle(10.0, 20.0, 0.7), vehicle_from_camera(200.0, -30.0, 0.1);
  const Eigen::Matrix3d p = Eigen::Vector3d(0.5, 0.2, 1e-4).asDiagonal();
  const Eigen::Matrix3d camera = CameraCovariance(world_from_vehicle, vehicle_from_camera, p);
  EXPECT_GT(camera(0, 0) + camera(1, 1), p(0, 0) + p(1, 1)) << "yaw uncertainty adds lever-arm error";
  const Eigen::Matrix3d back = VehicleCovariance(world_from_vehicle * vehicle_from_camera, vehicle_from_camera, camera);
  EXPECT_LT((back - p).norm(), 1e-9);
}

// A body that rolls out of the turn tilts the view toward its inside: registered frame to
// frame across an unmapped band in the turn, each link over-turns by a share of its turn that
// grows with the roll and the speed, the same way link after link. Exaggerated (5°/(m/s²) on
// a 3 m arc at 0.5 m/s: 0.42° of roll) to show over a short band. Given the roll, visual
// odometry takes it out; not given, the chain's yaw covariance (turn_sigma_fraction, set to
// this body's share) says how far off it may be.
class RollingExcursion : public Drive {
 protected:
  int MapCols() const override { return 24; }
  int MapRows() const override { return 10; }
  bool Mapped(int col) const override { return col < 7 || col > 15; }  // a band from x = 448 to 1024 mm
  struct Crossing {
    double yaw_error_max_deg = 0.0;  ///< off the map
    double yaw_sigma_ratio_min = 1e9;  ///< the yaw's standard deviation over its error, off the map
    int back_fixes = 0;  ///< fixes after the band
    Run run;
  };
  Crossing Cross(double roll_given_deg_per_mps2, double turn_sigma_fraction) {
    body_roll_deg_per_mps2_ = 5.0;
    options_.visual_odometry.roll_deg_per_mps2 = roll_given_deg_per_mps2;
    options_.visual_odometry.turn_sigma_fraction = turn_sigma_fraction;
    Crossing c;
    c.run = Localize(1.8, 0.5, Pose2());  // until the arc takes the view off the map's side
    bool crossed = false;
    for (std::size_t i = 0; i < c.run.errors_mm.size(); ++i) {
      if (c.run.states[i] == estimation::LockState::kOffMap) {
        crossed = true;
        const double e = std::abs(c.run.yaw_errors_deg[i]);
        c.yaw_error_max_deg = std::max(c.yaw_error_max_deg, e);
        if (e > 0.05) c.yaw_sigma_ratio_min = std::min(c.yaw_sigma_ratio_min, c.run.yaw_sigmas_deg[i] / e);
      } else if (crossed && c.run.fix_errors_mm[i] >= 0.0) {
        ++c.back_fixes;
      }
    }
    return c;
  }
};

TEST_F(RollingExcursion, VisualOdometryInATurnTakesTheBodysRollOut) {
  const Crossing given = Cross(5.0, 0.01);
  const Crossing unknown = Cross(0.0, 0.05);
  for (const Crossing* c : {&given, &unknown}) {
    ASSERT_FALSE(c->run.errors_mm.empty());
    EXPECT_GE(std::count(c->run.modes.begin(), c->run.modes.end(), Mode::kVisualOdometry), 20);
    EXPECT_EQ(c->run.lock_losses, 0);
    for (const double e : c->run.fix_errors_mm) EXPECT_LT(e, 1.0);
    EXPECT_GE(c->back_fixes, 5) << "back on the map";
  }
  RecordProperty("off_map_yaw_error_max_deg_roll_given", std::to_string(given.yaw_error_max_deg));
  RecordProperty("off_map_yaw_error_max_deg_roll_unknown", std::to_string(unknown.yaw_error_max_deg));
  EXPECT_GT(unknown.yaw_error_max_deg, 0.3) << "the roll over-turns the chain";
  EXPECT_LT(given.yaw_error_max_deg, 0.25 * unknown.yaw_error_max_deg);
  EXPECT_GT(unknown.yaw_sigma_ratio_min, 0.5) << "the covariance covers the bias";
}

// The same rolling body, its tilt estimated and its lever taken out. The last frames before
// the band hold seven templates, too few to measure the tilt, all on the band's near side.
// Registered as if the camera looked straight down, they turned with the roll as they lay
// (0.13 and 0.21 mm off, and a yaw 1.6 mrad off that the chain across the band carried to
// 0.9 mm, 4.8 times the estimate's standard deviation); registered through the tilt the
// frames before measured, they are on the truth, and the chain stays within its uncertainty.
TEST_F(RollingExcursion, AFixTooSparseForTheTiltIsRegisteredThroughThePredictedTilt) {
  body_roll_deg_per_mps2_ = 5.0;
  body_pivot_mm_ = 100.0;
  options_.visual_odometry.roll_deg_per_mps2 = 5.0;
  options_.tracker.templates.count = 12;
  options_.tracker.solver.estimate_tilt = true;
  options_.tilt_pivot_height_mm = 100.0;
  const Run run = Localize(1.8, 0.5, Pose2());
  ASSERT_FALSE(run.errors_mm.empty());
  EXPECT_EQ(run.lock_losses, 0);
  int sparse = 0, back = 0;
  double off_map_ratio_max = 0.0;
  for (std::size_t i = 0; i < run.errors_mm.size(); ++i) {
    if (run.fix_errors_mm[i] >= 0.0) {
      EXPECT_LT(run.fix_errors_mm[i], 0.1) << "frame " << i;
      if (run.inliers[i] < options_.tracker.solver.min_tilt_points) {
        ++sparse;
        EXPECT_LT(run.fix_errors_mm[i], 0.05) << "frame " << i << ", " << run.inliers[i] << " templates";
      }
      if (off_map_ratio_max > 0.0) ++back;
    }
    if (run.states[i] == estimation::LockState::kOffMap) {
      off_map_ratio_max = std::max(off_map_ratio_max, run.errors_mm[i] / run.sigmas_mm[i]);
    }
  }
  RecordProperty("off_map_error_over_sigma_max", std::to_string(off_map_ratio_max));
  EXPECT_GE(sparse, 1) << "frames too sparse for the tilt were fixed";
  EXPECT_GT(off_map_ratio_max, 0.0) << "the band was crossed";
  EXPECT_LT(off_map_ratio_max, 3.0);
  EXPECT_GE(back, 5) << "back on the map";
}

}  // namespace
}  // namespace mosaicloc::localizer
