#include "mosaicloc/sim/resample.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace mosaicloc::sim {
namespace {

// Keys' cubic convolution kernel weights for fractional offset f in [0, 1), a = -0.5.
inline void CubicWeights(double f, double w[4]) {
  constexpr double a = -0.5;
  const double x0 = 1.0 + f, x1 = f, x2 = 1.0 - f, x3 = 2.0 - f;
  w[0] = ((a * x0 - 5.0 * a) * x0 + 8.0 * a) * x0 - 4.0 * a;
  w[1] = ((a + 2.0) * x1 - (a + 3.0)) * x1 * x1 + 1.0;
  w[2] = ((a + 2.0) * x2 - (a + 3.0)) * x2 * x2 + 1.0;
  w[3] = ((a * x3 - 5.0 * a) * x3 + 8.0 * a) * x3 - 4.0 * a;
}

}  // namespace

cv::Mat ResampleExact(const cv::Mat& source, const Eigen::Matrix<double, 2, 3>& source_from_view, cv::Size size,
                      int supersampling) {
  if (source.empty() || source.type() != CV_8UC1) throw std::invalid_argument("ResampleExact: need CV_8UC1");
  if (supersampling < 1) throw std::invalid_argument("ResampleExact: supersampling must be >= 1");
  const int k = supersampling;
  const int max_x = source.cols - 1, max_y = source.rows - 1;
  cv::Mat out(size, CV_32FC1);
  for (int v = 0; v < size.height; ++v) {
    auto* o = out.ptr<float>(v);
    for (int u = 0; u < size.width; ++u) {
      double total = 0.0;
      for (int j = 0; j < k; ++j) {
        for (int i = 0; i < k; ++i) {
          const Eigen::Vector2d view(u + (i + 0.5) / k - 0.5, v + (j + 0.5) / k - 0.5);
          const Eigen::Vector2d p = source_from_view.leftCols<2>() * view + source_from_view.col(2);
          const double fx0 = std::floor(p.x()), fy0 = std::floor(p.y());
          double wx[4], wy[4];
          CubicWeights(p.x() - fx0, wx);
          CubicWeights(p.y() - fy0, wy);
          const int x0 = static_cast<int>(fx0) - 1, y0 = static_cast<int>(fy0) - 1;
          double value = 0.0;
          for (int r = 0; r < 4; ++r) {
            const std::uint8_t* row = source.ptr<std::uint8_t>(std::clamp(y0 + r, 0, max_y));
            double line = 0.0;
            for (int c = 0; c < 4; ++c) line += wx[c] * row[std::clamp(x0 + c, 0, max_x)];
            value += wy[r] * line;
          }
          total += value;
        }
      }
      o[u] = static_cast<float>(total / (k * k));
    }
  }
  return out;
}

}  // namespace mosaicloc::sim
