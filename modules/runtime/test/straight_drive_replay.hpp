#pragma once
// The replay tests' drive: a 1.5 m straight run over procedural concrete, mapped at its true
// poses at 0.5 m/s and driven again at 1.2 m/s with other noise and wheels 2 % larger than
// calibrated. Shared by the unit tests of the replay and the system tests of real floors.

#include <chrono>
#include <cstdio>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "mosaicloc/dataset/dataset.hpp"
#include "mosaicloc/dataset/fixes.hpp"
#include "mosaicloc/mosaic/builder.hpp"
#include "mosaicloc/mosaic/tile_store.hpp"
#include "mosaicloc/runtime/replay.hpp"
#include "mosaicloc/sim/simulator.hpp"
#include "mosaicloc/test/test_support.hpp"

namespace mosaicloc::runtime {

class StraightDriveReplay : public ::testing::Test {
 protected:
  // The mapping run (0.5 m/s, seed 5), or with `drive` the run localized (1.2 m/s, seed 6,
  // wheels 2 % larger than calibrated).
  static sim::SimulatorOptions Run(bool drive) {
    sim::SimulatorOptions options;
    options.route.name = "straight";
    options.route.straight_length_m = 1.5;
    options.laps = 1;
    options.route.speed_mps = drive ? 1.2 : 0.5;
    options.seed = drive ? 6 : 5;
    if (drive) {
      options.encoders.left_radius_error = 0.02;
      options.encoders.right_radius_error = 0.02;
    }
    return options;
  }

  static void SetUpTestSuite() {
    scratch_ = new test::ScratchDir();
    sim::Simulate(Run(false), scratch_->path() / "map-run", false);
    sim::Simulate(Run(true), scratch_->path() / "drive", false);
    PaintAtTruth(scratch_->path() / "map-run", scratch_->path() / "floor.mosaic");
  }

  // The map of the dataset `run` painted at its true poses into `map`.
  static void PaintAtTruth(const std::filesystem::path& run, const std::filesystem::path& map) {
    const dataset::DatasetReader reader(run);
    const dataset::Trajectory truth = reader.GroundTruth();
    mosaic::MapBuilder builder(mosaic::MapGrid{}, mosaic::Blend::kFeather);
    auto frames = reader.Frames();
    while (const auto frame = frames.Next()) {
      const auto pose = dataset::PoseAt(truth, frame->time, std::chrono::milliseconds(100));
      if (pose) builder.AddFrame(frame->image, *pose * reader.info().camera.vehicle_from_camera, 0.25);
    }
    auto store = mosaic::TileStore::Create(map, mosaic::MapGrid{});
    builder.Write(*store);
  }
  static void TearDownTestSuite() {
    delete scratch_;
    scratch_ = nullptr;
  }

  // The replay of the drive in `dataset` (of the scratch directory) against the map, its
  // report in `out`.
  static ReplayOptions Options(ReplayMode mode, const std::string& out, const std::string& dataset = "drive") {
    ReplayOptions options;
    options.dataset = scratch_->path() / dataset;
    options.map = scratch_->path() / "floor.mosaic";
    options.out = scratch_->path() / out;
    options.mode = mode;
    // A straight drive passes no place twice: nothing to register (the revisits are measured
    // on a drive that does, in the command-line tests).
    options.revisit_places = 0;
    return options;
  }

  static std::vector<dataset::FrameReport> Fixes(const ReplaySummary& summary) {
    return dataset::ReadFixesCsv(summary.report / "fixes.csv");
  }

  // A replay that holds the lock with no wrong fix, at least `fix_rate` of the frames fixed,
  // within `rms_mm` and `max_mm` of the truth.
  static void ExpectHeld(const dataset::Metrics& m, double fix_rate, double rms_mm, double max_mm) {
    ASSERT_TRUE(m.fix_rate && m.wrong_fixes && m.position_rms_mm && m.position_max_mm && m.lock_losses);
    std::printf("%.4f fixes, %lld wrong, %lld lock losses, position %.4f / %.4f mm RMS / max\n", *m.fix_rate,
                static_cast<long long>(*m.wrong_fixes), static_cast<long long>(*m.lock_losses), *m.position_rms_mm,
                *m.position_max_mm);
    EXPECT_GE(*m.fix_rate, fix_rate);
    EXPECT_EQ(*m.wrong_fixes, 0);
    EXPECT_EQ(*m.lock_losses, 0);
    EXPECT_LT(*m.position_rms_mm, rms_mm);
    EXPECT_LT(*m.position_max_mm, max_mm);
  }

  inline static test::ScratchDir* scratch_ = nullptr;
};

}  // namespace mosaicloc::runtime
