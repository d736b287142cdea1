// The console's HTTP request handling (console::Console on cpp-httplib) as a hostile client
// meets it: the input is the bytes of one connection to a console serving a small map and a
// report, a token required (Console::Answer: the server's own parsing, token check, rate limit
// and routes, without a socket). Whatever arrives gets an answer or the connection's end.
#include <fstream>

#include <opencv2/core.hpp>

#include "fuzz_input.hpp"
#include "mosaicloc/console/console.hpp"
#include "mosaicloc/core/log.hpp"
#include "mosaicloc/dataset/fixes.hpp"
#include "mosaicloc/mosaic/tile_store.hpp"

namespace {

std::unique_ptr<mosaicloc::console::Console> SmallConsole() {
  mosaicloc::core::Log().set_level(spdlog::level::off);
  const std::filesystem::path map = mosaicloc::fuzz::ScratchDir() / "console.mosaic";
  std::filesystem::remove(map);
  {
    mosaicloc::mosaic::MapGrid grid;
    grid.tile_size_px = 32;
    grid.levels = 2;
    auto store = mosaicloc::mosaic::TileStore::Create(map, grid);
    cv::Mat pixels(32, 32, CV_8UC1, cv::Scalar(90));
    store->Write({{{0, 0, 0}, pixels}, {{1, 0, 0}, pixels}});
    store->WriteQuality(1, {{0, 0, 1.0f, 30.0f, 0.2f}});
  }
  const std::filesystem::path report = mosaicloc::fuzz::ScratchDir() / "report";
  std::filesystem::create_directories(report);
  std::ofstream(report / "metrics.json") << R"({"frames": 1, "wrong_fixes": 0})";
  mosaicloc::dataset::FrameReport row;
  row.time = mosaicloc::core::Timestamp::FromNanoseconds(1'000'000'000LL);
  row.status = 1;
  row.fixed = true;
  std::ofstream(report / "fixes.csv") << mosaicloc::dataset::FixesCsvHeader() << mosaicloc::dataset::FixesCsvRow(row);
  mosaicloc::console::ConsoleOptions options;
  options.listen = "127.0.0.1:0";
  options.token = "fuzzing-token-0123456789";
  options.reports = {report};
  options.live_run = true;
  options.stream_hz = 100.0;
  return std::make_unique<mosaicloc::console::Console>(options, map);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const std::unique_ptr<mosaicloc::console::Console> console = SmallConsole();
  const std::string answer = console->Answer(std::string_view(reinterpret_cast<const char*>(data), size));
  // Every answer starts with a status line (or there is none: the connection just ends).
  if (!answer.empty() && !answer.starts_with("HTTP/1.1 ")) __builtin_trap();
  return 0;
}
