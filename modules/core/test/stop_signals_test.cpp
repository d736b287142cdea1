#include "mosaicloc/core/stop_signals.hpp"

#include <csignal>

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
    std::raise(SIGINT);
    EXPECT_EQ(*StopSignals::Reason(), "interrupted (SIGINT)");
  }
  EXPECT_TRUE(DefaultHandler(SIGINT));
  EXPECT_TRUE(DefaultHandler(SIGTERM));
  const StopSignals again;
  EXPECT_FALSE(StopSignals::Reason()) << "a new guard starts without a reason";
}

}  // namespace
}  // namespace mosaicloc::core
