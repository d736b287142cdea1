#include "mosaicloc/calibration/flat_field.hpp"

#include <algorithm>

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "mosaicloc/core/error.hpp"

namespace mosaicloc::calibration {
namespace {

// Monomials u^i v^j, i + j <= degree, of coordinates scaled to [-1, 1].
Eigen::VectorXd FlatFieldMonomials(double u, double v, int degree) {
  Eigen::VectorXd m((degree + 1) * (degree + 2) / 2);
  int k = 0;
  double ui = 1.0;
  for (int i = 0; i <= degree; ++i, ui *= u) {
    double vj = 1.0;
    for (int j = 0; i + j <= degree; ++j, vj *= v) m(k++) = ui * vj;
  }
  return m;
}

}  // namespace

void FlatFieldEstimator::Add(const cv::Mat& frame) {
  if (frame.empty() || frame.type() != CV_8UC1) core::ThrowInvalidInput("flat field: frames must be 8-bit grey");
  if (frames_ == 0) {
    size_ = frame.size();
    const int cols = (size_.width + stride_ - 1) / stride_, rows = (size_.height + stride_ - 1) / stride_;
    samples_.assign(static_cast<std::size_t>(cols) * static_cast<std::size_t>(rows), {});
  } else if (frame.size() != size_) {
    core::ThrowInvalidInput("flat field: frames differ in size");
  }
  std::size_t k = 0;
  for (int y = 0; y < size_.height; y += stride_) {
    const unsigned char* row = frame.ptr<unsigned char>(y);
    for (int x = 0; x < size_.width; x += stride_) samples_[k++].push_back(row[x]);
  }
  ++frames_;
}

cv::Mat FlatFieldEstimator::Gain(int degree) const {
  if (frames_ == 0) return cv::Mat();
  const int terms = (degree + 1) * (degree + 2) / 2;
  const double half_w = 0.5 * (size_.width - 1), half_h = 0.5 * (size_.height - 1);
  Eigen::MatrixXd normal = Eigen::MatrixXd::Zero(terms, terms);
  Eigen::VectorXd rhs = Eigen::VectorXd::Zero(terms);
  std::size_t k = 0;
  std::vector<unsigned char> values;
  for (int y = 0; y < size_.height; y += stride_) {
    for (int x = 0; x < size_.width; x += stride_) {
      values = samples_[k++];
      auto middle = values.begin() + static_cast<long>(values.size() / 2);
      std::nth_element(values.begin(), middle, values.end());
      const Eigen::VectorXd m = FlatFieldMonomials(x / half_w - 1.0, y / half_h - 1.0, degree);
      normal.selfadjointView<Eigen::Lower>().rankUpdate(m);
      rhs += m * static_cast<double>(*middle);
    }
  }
  const Eigen::VectorXd c = normal.selfadjointView<Eigen::Lower>().ldlt().solve(rhs);
  cv::Mat gain(size_, CV_32F);
  for (int y = 0; y < size_.height; ++y) {
    float* row = gain.ptr<float>(y);
    for (int x = 0; x < size_.width; ++x) {
      row[x] = static_cast<float>(FlatFieldMonomials(x / half_w - 1.0, y / half_h - 1.0, degree).dot(c));
    }
  }
  const double mean = cv::mean(gain)[0];
  if (!(mean > 0.0)) return cv::Mat(size_, CV_32F, cv::Scalar(1.0));
  gain /= mean;
  return gain;
}

cv::Mat DivideByGain(const cv::Mat& frame, const cv::Mat& gain) {
  if (gain.empty()) return frame;
  cv::Mat value;
  frame.convertTo(value, CV_32F);
  cv::divide(value, gain, value);
  cv::Mat out;
  value.convertTo(out, CV_8U);  // rounds and saturates
  return out;
}

}  // namespace mosaicloc::calibration
