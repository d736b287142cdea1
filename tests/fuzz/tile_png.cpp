// A map tile's PNG as the map file holds it (TileStore::Decode, the project's own reader of
// zlib level 0 IDAT streams, with libpng behind it for the rest).
#include <vector>

#include <opencv2/core/mat.hpp>

#include "fuzz_input.hpp"
#include "mosaicloc/mosaic/tile_store.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::vector<unsigned char> png(data, data + size);
  cv::Mat pixels;
  mosaicloc::fuzz::ExpectOnlyCoreErrors([&] {
    // A tile that decodes is 256 x 256 grey; one that does not says why.
    const std::string problem = mosaicloc::mosaic::TileStore::Decode(png, 256, pixels);
    if (problem.empty() && (pixels.rows != 256 || pixels.cols != 256 || pixels.type() != CV_8UC1)) __builtin_trap();
  });
  return 0;
}
