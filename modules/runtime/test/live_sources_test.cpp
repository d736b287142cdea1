#include "mosaicloc/runtime/live_sources.hpp"

#include <chrono>
#include <memory>
#include <thread>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "mosaicloc/io/plc_link.hpp"

namespace mosaicloc::runtime {
namespace {

std::shared_ptr<const sim::PlannedDrive> SmallDrive(std::int64_t frames) {
  sim::SimulatorOptions options;
  options.camera = camera::IdealCameraOptions{160, 120, 0.25};
  options.frames = frames;
  options.route.name = "loop";
  options.drop_probability = 0.2;
  options.seed = 5;
  return std::make_shared<const sim::PlannedDrive>(options);
}

// The simulator as a camera: every planned frame, in order, the image the plan renders, stamped
// at its capture instant after the start, and never delivered before that instant.
TEST(SimulatedFrameSource, DeliversThePlannedFramesAtTheirInstants) {
  const auto drive = SmallDrive(12);
  SimulatedFrameSource source(drive, 0.0);
  const core::Timestamp start = io::MonotonicNow();
  std::size_t k = 0;
  while (const auto frame = source.Next()) {
    ASSERT_LT(k, drive->capture_s().size());
    EXPECT_EQ(frame->sequence, static_cast<std::int64_t>(k));
    const double at_s = core::ToSeconds(frame->time - start);
    EXPECT_NEAR(at_s, drive->capture_s()[k], 0.02) << "frame " << k;
    EXPECT_GE(io::MonotonicNow(), frame->time) << "frame " << k << " came before its instant";
    EXPECT_EQ(cv::norm(frame->image, drive->RenderFrame(k), cv::NORM_INF), 0.0) << "frame " << k;
    ++k;
  }
  EXPECT_EQ(k, drive->capture_s().size());
  EXPECT_LT(k, 12U) << "a fifth of the frames dropped, as planned";
  EXPECT_NE(source.Describe().find("rendered as they are due"), std::string::npos) << source.Describe();
}

// Stopped (a clean stop of the run), the source ends while it waits for the next instant.
TEST(SimulatedFrameSource, StopEndsTheWait) {
  const auto drive = SmallDrive(900);  // 30 s of frames
  SimulatedFrameSource source(drive, 0.0);
  ASSERT_TRUE(source.Next());
  std::thread stopper([&source] {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    source.Stop();
  });
  std::size_t delivered = 1;
  while (source.Next()) ++delivered;
  stopper.join();
  EXPECT_LT(delivered, 20U);
}

// A start in the future is that far ahead on the monotonic clock.
TEST(Playback, StartsAtTheGivenWallClockInstant) {
  const double wall_now_s =
      std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
  const Playback playback = Playback::Starting(core::Timestamp::FromSeconds(3.0), wall_now_s + 2.0);
  EXPECT_NEAR(core::ToSeconds(playback.start - io::MonotonicNow()), 2.0, 0.5);
  EXPECT_EQ(playback.ToMonotonic(core::Timestamp::FromSeconds(4.0)), playback.start + std::chrono::seconds(1));
  EXPECT_EQ(playback.ToDataset(playback.start), core::Timestamp::FromSeconds(3.0));
}

}  // namespace
}  // namespace mosaicloc::runtime
