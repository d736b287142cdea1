// A recorded frame's PNG (dataset::DecodeGreyPng, the project's own unfiltering of libdeflate's
// output): an image it accepts must be the one OpenCV (libpng, zlib) decodes from the same bytes.
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "fuzz_input.hpp"
#include "mosaicloc/dataset/frame_png.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  cv::Mat pixels;
  if (!mosaicloc::dataset::DecodeGreyPng(data, size, pixels)) return 0;
  const std::vector<unsigned char> png(data, data + size);
  const cv::Mat reference = cv::imdecode(png, cv::IMREAD_UNCHANGED);
  if (reference.empty() || reference.size() != pixels.size() || reference.type() != CV_8UC1 ||
      cv::norm(reference, pixels, cv::NORM_INF) != 0.0) {
    __builtin_trap();
  }
  return 0;
}
