#include "pyramid.hpp"

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "mosaicloc/mosaic/tile_store.hpp"

namespace mosaicloc::mosaic::internal {

cv::Mat Downsample(const std::array<cv::Mat, 4>& children, int tile_size_px) {
  const int t = tile_size_px;
  cv::Mat mosaic = cv::Mat::zeros(2 * t, 2 * t, CV_8UC1);
  for (int i = 0; i < 4; ++i) {
    if (!children[static_cast<std::size_t>(i)].empty()) {
      children[static_cast<std::size_t>(i)].copyTo(mosaic(cv::Rect((i % 2) * t, (i / 2) * t, t, t)));
    }
  }
  cv::Mat mapped;
  cv::Mat(mosaic != kUnmapped).convertTo(mapped, CV_32F, 1.0 / 255.0);
  cv::Mat values;
  mosaic.convertTo(values, CV_32F);
  cv::Mat sum;
  cv::Mat count;
  cv::resize(values, sum, cv::Size(t, t), 0, 0, cv::INTER_AREA);   // mean of four, unmapped as 0
  cv::resize(mapped, count, cv::Size(t, t), 0, 0, cv::INTER_AREA);  // fraction of the four mapped
  cv::Mat mean;
  cv::divide(sum, cv::max(count, 1e-6), mean);
  cv::Mat out;
  mean.convertTo(out, CV_8U);
  cv::max(out, 1, out);
  out.setTo(cv::Scalar(kUnmapped), count < 0.01);
  return out;
}

}  // namespace mosaicloc::mosaic::internal
