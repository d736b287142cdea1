#include "mosaicloc/core/stop_signals.hpp"

#include <csignal>
#include <cstdlib>

#include <gtest/gtest.h>

namespace mosaicloc::core {
namespace {

bool DefaultHandler(int signal) {
  struct sigaction current {};
  sigaction(signal, nullptr, &current);
  return current.sa_handler == SIG_DFL;
}

TEST(StopSignalsTest, ASignalIsAReasonToStopNotAnEnd) {
  {
    const StopSignals signals;
    EXPECT_FALSE(StopSignals::Reason());
    std::raise(SIGTERM);
    ASSERT_TRUE(StopSignals::Reason());
    EXPECT_EQ(*StopSignals::Reason(), "terminated (SIGTERM)");
    EXPECT_EQ(StopSignals::Signal(), SIGTERM);
  }
  EXPECT_TRUE(DefaultHandler(SIGINT));
  EXPECT_TRUE(DefaultHandler(SIGTERM));
  const StopSignals again;
  EXPECT_FALSE(StopSignals::Reason()) << "a new guard starts without a reason";
  EXPECT_EQ(StopSignals::Signal(), 0);
  std::raise(SIGINT);
  EXPECT_EQ(*StopSignals::Reason(), "interrupted (SIGINT)");
}

TEST(StopSignalsDeathTest, ASecondSignalWhileStoppingKills) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  EXPECT_EXIT(
      {
        const StopSignals signals;
        std::raise(SIGINT);
        std::raise(SIGINT);
        std::_Exit(0);  // not reached
      },
      testing::KilledBySignal(SIGINT), "");
}

TEST(StoppedTest, CarriesTheSignalForTheExitStatus) {
  const Stopped stopped(SIGTERM, "map build: terminated (SIGTERM) at 40 %");
  EXPECT_EQ(stopped.signal(), SIGTERM);
  EXPECT_STREQ(stopped.what(), "map build: terminated (SIGTERM) at 40 %");
}

}  // namespace
}  // namespace mosaicloc::core
