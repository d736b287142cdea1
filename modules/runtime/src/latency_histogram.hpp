#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

namespace mosaicloc::runtime {

// Times in 10 us buckets up to 500 ms (and one beyond): percentiles to 10 us in a fixed
// 400 KiB, so a long run's bookkeeping does not grow with the frames it measures.
class LatencyHistogram {
 public:
  void Add(double ms) {
    const auto bucket = static_cast<std::size_t>(std::max(0.0, ms) / kBucketMs);
    ++counts_[std::min(bucket, counts_.size() - 1)];
    ++total_;
    max_ms_ = std::max(max_ms_, ms);
  }
  std::int64_t count() const { return total_; }
  // The upper edge of the bucket holding the p-th percentile, ms (0 when empty).
  double Percentile(double p) const {
    if (total_ == 0) return 0.0;
    const auto rank = static_cast<std::int64_t>(std::ceil(p / 100.0 * static_cast<double>(total_)));
    std::int64_t seen = 0;
    for (std::size_t b = 0; b < counts_.size(); ++b) {
      seen += counts_[b];
      if (seen >= std::max<std::int64_t>(rank, 1)) return std::min(static_cast<double>(b + 1) * kBucketMs, max_ms_);
    }
    return max_ms_;
  }
  double max_ms() const { return max_ms_; }

 private:
  static constexpr double kBucketMs = 0.01;
  std::vector<std::int64_t> counts_ = std::vector<std::int64_t>(50'001, 0);
  std::int64_t total_ = 0;
  double max_ms_ = 0.0;
};

}  // namespace mosaicloc::runtime
