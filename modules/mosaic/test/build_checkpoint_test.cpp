#include <sqlite3.h>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/mosaic/build_checkpoint.hpp"
#include "mosaicloc/mosaic/builder.hpp"
#include "mosaicloc/mosaic/tile_store.hpp"
#include "mosaicloc/test/test_support.hpp"

namespace mosaicloc::mosaic {
namespace {

using ::testing::HasSubstr;

// Frames of smoothed noise along a gentle curve, as a drive would give them.
std::vector<std::pair<core::Pose2, cv::Mat>> Frames(int count) {
  std::vector<std::pair<core::Pose2, cv::Mat>> frames;
  cv::RNG rng(9);
  for (int i = 0; i < count; ++i) {
    cv::Mat frame(120, 160, CV_8UC1);
    rng.fill(frame, cv::RNG::UNIFORM, 0, 256);
    cv::GaussianBlur(frame, frame, cv::Size(0, 0), 1.0);
    frames.emplace_back(core::Pose2(20.0 + 9.0 * i, -30.0 - 2.0 * i, 0.04 * i), frame);
  }
  return frames;
}

// Every tile of a map, as stored (PNG bytes and CRC).
std::vector<std::pair<std::string, std::vector<unsigned char>>> Tiles(const TileStore& store) {
  std::vector<std::pair<std::string, std::vector<unsigned char>>> tiles;
  for (const auto& key : store.List()) tiles.emplace_back(key.ToString(), TileStore::Encode(store.Read(key).pixels));
  return tiles;
}

const std::map<std::string, std::string> kIdentity = {{"dataset", "/data/drive"}, {"blend", "feather"}};

TEST(BuildCheckpoint, ResumedBuildEqualsAnUninterruptedOne) {
  test::ScratchDir dir;
  MapGrid grid;
  grid.tile_size_px = 64;
  grid.levels = 2;
  const auto frames = Frames(10);
  for (const Blend blend : {Blend::kFeather, Blend::kBestView}) {
    MapBuilder whole(grid, blend);
    for (const auto& [pose, frame] : frames) whole.AddFrame(frame, pose, 0.25);
    const auto reference = TileStore::Create(dir / ("whole" + std::to_string(static_cast<int>(blend)) + ".mosaic"), grid);
    whole.Write(*reference);

    const auto file = dir / "b.checkpoint";
    {
      // Interrupted after 4 frames, with a save after 2 and one after 4.
      MapBuilder first(grid, blend);
      auto checkpoint = BuildCheckpoint::Create(file, kIdentity);
      for (int i = 0; i < 4; ++i) {
        first.AddFrame(frames[static_cast<std::size_t>(i)].second, frames[static_cast<std::size_t>(i)].first, 0.25);
        if (i % 2 == 1) checkpoint->Save(first, i + 1, {{"skipped", 7}});
      }
    }
    MapBuilder resumed(grid, blend);
    const auto checkpoint = BuildCheckpoint::Open(file, kIdentity);
    EXPECT_EQ(checkpoint->frames_done(), 4);
    EXPECT_EQ(checkpoint->counter("skipped"), 7);
    checkpoint->Restore(resumed);
    EXPECT_EQ(resumed.frames(), 4);
    for (std::size_t i = 4; i < frames.size(); ++i) resumed.AddFrame(frames[i].second, frames[i].first, 0.25);
    EXPECT_EQ(resumed.frames(), 10);
    const auto result = TileStore::Create(dir / ("resumed" + std::to_string(static_cast<int>(blend)) + ".mosaic"), grid);
    resumed.Write(*result);
    EXPECT_GT(result->Count(0), 4);
    EXPECT_TRUE(Tiles(*result) == Tiles(*reference)) << "blend " << static_cast<int>(blend);
  }
}

TEST(BuildCheckpoint, RefusesAnotherBuildsCheckpointAndDamage) {
  test::ScratchDir dir;
  MapGrid grid;
  grid.tile_size_px = 64;
  const auto file = dir / "c.checkpoint";
  {
    MapBuilder builder(grid, Blend::kFeather);
    for (const auto& [pose, frame] : Frames(3)) builder.AddFrame(frame, pose, 0.25);
    BuildCheckpoint::Create(file, kIdentity)->Save(builder, 3, {});
  }
  try {
    BuildCheckpoint::Open(file, {{"dataset", "/data/drive"}, {"blend", "best-view"}});
    FAIL() << "opened another build's checkpoint";
  } catch (const core::Error& e) {
    EXPECT_THAT(e.what(), HasSubstr("made by a build with blend 'feather', not 'best-view'"));
  }
  EXPECT_THROW(BuildCheckpoint::Open(file, {{"dataset", "/data/drive"}}), core::Error);  // a setting fewer
  // Not a map: opening it as one fails, saying so.
  EXPECT_THROW(TileStore::Open(file, false), core::Error);

  // A damaged accumulator is named, never restored.
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(file.c_str(), &db), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(db, "UPDATE accumulators SET data = zeroblob(length(data)) WHERE rowid = (SELECT MIN(rowid) FROM accumulators)",
                         nullptr, nullptr, nullptr),
            SQLITE_OK);
  sqlite3_close(db);
  MapBuilder builder(grid, Blend::kFeather);
  try {
    BuildCheckpoint::Open(file, kIdentity)->Restore(builder);
    FAIL() << "restored a damaged tile";
  } catch (const core::Error& e) {
    EXPECT_THAT(e.what(), HasSubstr("c.checkpoint: saved tile level 0 col"));
    EXPECT_THAT(e.what(), HasSubstr("is damaged"));
  }
}

}  // namespace
}  // namespace mosaicloc::mosaic
