#include "mosaicloc/core/error.hpp"

#include <gtest/gtest.h>

#include "mosaicloc/core/log.hpp"

namespace mosaicloc::core {
namespace {

enum class MatchFailure { kNoTexture, kAmbiguous };

Result<double, MatchFailure> Match(bool textured) {
  if (!textured) return Fail(MatchFailure::kNoTexture);
  return 0.25;
}

TEST(Result, CarriesValueOrReason) {
  const auto good = Match(true);
  ASSERT_TRUE(good.ok());
  EXPECT_DOUBLE_EQ(good.value(), 0.25);
  EXPECT_THROW(good.error(), std::logic_error);

  const auto bad = Match(false);
  ASSERT_FALSE(bad);
  EXPECT_EQ(bad.error(), MatchFailure::kNoTexture);
  EXPECT_THROW(bad.value(), std::logic_error);
}

TEST(Error, KindsAreDistinguishable) {
  try {
    ThrowInvalidInput("a.yaml:3: camera.width_px: must be > 0");
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.kind(), ErrorKind::kInvalidInput);
    EXPECT_STREQ(e.what(), "a.yaml:3: camera.width_px: must be > 0");
  }
  try {
    ThrowRuntime("disk full");
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.kind(), ErrorKind::kRuntime);
  }
}

TEST(Log, LevelsParseAndUnknownIsRejected) {
  EXPECT_EQ(ParseLogLevel("warning"), LogLevel::kWarning);
  EXPECT_THROW(ParseLogLevel("verbose"), Error);
  SetLogLevel(LogLevel::kError);
  EXPECT_EQ(Log().level(), spdlog::level::err);
  SetLogLevel(LogLevel::kInfo);
}

}  // namespace
}  // namespace mosaicloc::core
