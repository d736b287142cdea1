#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "floor_internal.hpp"
#include "mosaicloc/core/error.hpp"
#include "mosaicloc/sim/floor.hpp"

namespace mosaicloc::sim {
namespace {

constexpr int kMinImageSidePx = 16;

/// Any decoded image as 8-bit grey: colour by the ITU-R BT.601 luma weights (cv::cvtColor),
/// alpha dropped, 16-bit scaled by 255/65535, float taken as 0..1.
cv::Mat ToGrey8(const cv::Mat& decoded) {
  cv::Mat grey;
  switch (decoded.channels()) {
    case 1: grey = decoded; break;
    case 3: cv::cvtColor(decoded, grey, cv::COLOR_BGR2GRAY); break;
    case 4: cv::cvtColor(decoded, grey, cv::COLOR_BGRA2GRAY); break;
    default: cv::extractChannel(decoded, grey, 0); break;
  }
  switch (grey.depth()) {
    case CV_8U: return grey;
    case CV_8S: grey.convertTo(grey, CV_8U, 1.0, 128.0); return grey;
    case CV_16U: grey.convertTo(grey, CV_8U, 255.0 / 65535.0); return grey;
    case CV_16S: grey.convertTo(grey, CV_8U, 255.0 / 65535.0, 128.0); return grey;
    case CV_32F:
    case CV_64F:
    case CV_16F: grey.convertTo(grey, CV_8U, 255.0); return grey;
    default: {
      double min_value = 0.0;
      double max_value = 0.0;
      cv::minMaxLoc(grey, &min_value, &max_value);
      const double scale = max_value > min_value ? 255.0 / (max_value - min_value) : 1.0;
      grey.convertTo(grey, CV_8U, scale, -min_value * scale);
      return grey;
    }
  }
}

class ImageFloor final : public Floor {
 public:
  ImageFloor(cv::Mat image, ImageFloorOptions options)
      : image_(std::move(image)), options_(std::move(options)) {}

  double mm_per_texel() const override { return options_.mm_per_texel; }

  cv::Mat Render(std::int64_t col0, std::int64_t row0, int cols, int rows) const override {
    internal::CheckWindowSize(cols, rows);
    cv::Mat out(rows, cols, CV_8UC1);
    const int width = image_.cols;
    const int height = image_.rows;
    const int first_col = static_cast<int>(internal::FloorMod(col0, width));
    const int first_row = static_cast<int>(internal::FloorMod(row0, height));
    for (int y = 0; y < rows; ++y) {
      const std::uint8_t* source = image_.ptr<std::uint8_t>((first_row + y) % height);
      std::uint8_t* target = out.ptr<std::uint8_t>(y);
      int x = 0;
      int source_col = first_col;
      while (x < cols) {
        const int run = std::min(cols - x, width - source_col);
        std::memcpy(target + x, source + source_col, static_cast<std::size_t>(run));
        x += run;
        source_col = 0;
      }
    }
    return out;
  }

  std::string Describe() const override {
    std::ostringstream text;
    text << "image file=" << options_.image.string() << " size=" << image_.cols << "x"
         << image_.rows << " mm_per_texel=" << options_.mm_per_texel;
    return text.str();
  }

 private:
  cv::Mat image_;  // CV_8UC1, never modified: safe to read from several threads
  ImageFloorOptions options_;
};

/// The picture cut into squares at places drawn from the seed, each turned by a multiple of
/// 90 degrees and perhaps mirrored (one of the square's eight symmetries, also drawn), blended
/// where they overlap (ImageFloorOptions::layout "patches").
///
/// Square (i, j) is centred on texel (i P, j P), P the spacing. Along each axis its weight at
/// a texel d from its centre is clamp((P/2 + B/2 - |d|) / B, 0, 1), B = P/4 the blend: 1 over
/// its middle, falling to 0 across the band it shares with its neighbour, and the weights of
/// two neighbours sum to 1 there. A texel is mean + sum w_k (s_k - mean) / sqrt(sum w_k^2),
/// s_k what square k cut from the picture: where one square covers it that is a texel of the
/// picture; in a band the sum of independent deviations is scaled back to their variance.
class PatchedImageFloor final : public Floor {
 public:
  PatchedImageFloor(cv::Mat image, ImageFloorOptions options, int spacing)
      : image_(std::move(image)),
        options_(std::move(options)),
        spacing_(spacing),
        blend_(std::max(2, spacing / 4)),
        reach_((spacing + blend_ + 1) / 2),
        mean_(cv::mean(image_)[0]),
        key_(internal::LayerKey(options_.seed, kLayer)) {}

  double mm_per_texel() const override { return options_.mm_per_texel; }

  cv::Mat Render(std::int64_t col0, std::int64_t row0, int cols, int rows) const override {
    internal::CheckWindowSize(cols, rows);
    cv::Mat out(rows, cols, CV_8UC1);
    if (cols == 0 || rows == 0) return out;
    cv::Mat deviation(rows, cols, CV_32FC1, cv::Scalar(0.0));
    cv::Mat weight_squares(rows, cols, CV_32FC1, cv::Scalar(0.0));
    const std::int64_t first_i = internal::FloorDiv(col0 - reach_, spacing_);
    const std::int64_t last_i = internal::FloorDiv(col0 + cols - 1 + reach_, spacing_) + 1;
    const std::int64_t first_j = internal::FloorDiv(row0 - reach_, spacing_);
    const std::int64_t last_j = internal::FloorDiv(row0 + rows - 1 + reach_, spacing_) + 1;
    std::vector<float> weight_x;
    for (std::int64_t j = first_j; j <= last_j; ++j) {
      const std::int64_t centre_r = j * spacing_;
      const std::int64_t r_begin = std::max(row0, centre_r - reach_ + 1);
      const std::int64_t r_end = std::min(row0 + rows, centre_r + reach_);
      if (r_begin >= r_end) continue;
      for (std::int64_t i = first_i; i <= last_i; ++i) {
        const std::int64_t centre_c = i * spacing_;
        const std::int64_t c_begin = std::max(col0, centre_c - reach_ + 1);
        const std::int64_t c_end = std::min(col0 + cols, centre_c + reach_);
        if (c_begin >= c_end) continue;
        // Where the square's centre is in the picture, and how it is turned and mirrored: the
        // picture's texel for (du, dv) off the centre is centre + du a + dv b.
        internal::CellRandom random(internal::CellKey(key_, i, j));
        const auto span = static_cast<std::uint64_t>(2 * reach_ - 1);
        const auto source_x = static_cast<std::int64_t>(random.Next() % (static_cast<std::uint64_t>(image_.cols) - span + 1));
        const auto source_y = static_cast<std::int64_t>(random.Next() % (static_cast<std::uint64_t>(image_.rows) - span + 1));
        const auto orientation = static_cast<int>(random.Next() % 8U);
        const std::uint8_t* centre = image_.ptr<std::uint8_t>(static_cast<int>(source_y + reach_ - 1)) + (source_x + reach_ - 1);
        const auto step = static_cast<std::ptrdiff_t>(image_.step1());
        const std::ptrdiff_t sign_u = (orientation & 1) != 0 ? -1 : 1;
        const std::ptrdiff_t sign_v = (orientation & 2) != 0 ? -1 : 1;
        const bool transposed = (orientation & 4) != 0;
        const std::ptrdiff_t a = sign_u * (transposed ? step : 1);
        const std::ptrdiff_t b = sign_v * (transposed ? 1 : step);
        const int n = static_cast<int>(c_end - c_begin);
        weight_x.resize(static_cast<std::size_t>(n));
        for (int k = 0; k < n; ++k) weight_x[static_cast<std::size_t>(k)] = Weight(c_begin + k - centre_c);
        const float mean = static_cast<float>(mean_);
        for (std::int64_t r = r_begin; r < r_end; ++r) {
          const float weight_y = Weight(r - centre_r);
          if (weight_y <= 0.0F) continue;
          const std::uint8_t* source = centre + static_cast<std::ptrdiff_t>(r - centre_r) * b +
                                       static_cast<std::ptrdiff_t>(c_begin - centre_c) * a;
          float* sum = deviation.ptr<float>(static_cast<int>(r - row0)) + (c_begin - col0);
          float* squares = weight_squares.ptr<float>(static_cast<int>(r - row0)) + (c_begin - col0);
          for (int k = 0; k < n; ++k) {
            const float w = weight_x[static_cast<std::size_t>(k)] * weight_y;
            sum[k] += w * (static_cast<float>(source[static_cast<std::ptrdiff_t>(k) * a]) - mean);
            squares[k] += w * w;
          }
        }
      }
    }
    for (int y = 0; y < rows; ++y) {
      const float* sum = deviation.ptr<float>(y);
      const float* squares = weight_squares.ptr<float>(y);
      std::uint8_t* target = out.ptr<std::uint8_t>(y);
      for (int x = 0; x < cols; ++x) {
        target[x] = cv::saturate_cast<std::uint8_t>(mean_ + sum[x] / std::sqrt(squares[x]));
      }
    }
    return out;
  }

  std::string Describe() const override {
    std::ostringstream text;
    text << "image file=" << options_.image.string() << " size=" << image_.cols << "x"
         << image_.rows << " mm_per_texel=" << options_.mm_per_texel << " layout=patches patch_mm="
         << options_.patch_mm << " seed=" << options_.seed;
    return text.str();
  }

 private:
  static constexpr std::uint64_t kLayer = 0x7061746368ULL;  // "patch"

  /// A square's weight along one axis at `d` texels from its centre.
  float Weight(std::int64_t d) const {
    const double w = (0.5 * (spacing_ + blend_) - static_cast<double>(std::abs(d))) / blend_;
    return static_cast<float>(std::clamp(w, 0.0, 1.0));
  }

  cv::Mat image_;  // CV_8UC1, never modified: safe to read from several threads
  ImageFloorOptions options_;
  std::int64_t spacing_;
  std::int64_t blend_;
  std::int64_t reach_;  // a square's weight is 0 from this many texels off its centre
  double mean_;
  std::uint64_t key_;
};

/// The spacing of the patches in texels (a million at most: no picture is that large).
int PatchSpacing(const ImageFloorOptions& options) {
  return static_cast<int>(std::lround(std::min(1e6, options.patch_mm / options.mm_per_texel)));
}

}  // namespace

bool ImageFloorOptions::Check(std::string* why) const {
  auto fail = [why](const std::string& reason) {
    if (why != nullptr) *why = reason;
    return false;
  };
  if (image.empty()) return fail("image floor: image: no file given");
  if (!std::isfinite(mm_per_texel) || mm_per_texel <= 0.0 || mm_per_texel > 100.0) {
    return fail("image floor: mm_per_texel = " + std::to_string(mm_per_texel) +
                ": must be in (0, 100]");
  }
  if (layout != "repeat" && layout != "patches") {
    return fail("image floor: layout '" + layout + "': must be repeat or patches");
  }
  if (layout == "patches") {
    if (!std::isfinite(patch_mm) || patch_mm <= 0.0 || patch_mm > 10000.0) {
      return fail("image floor: patch_mm = " + std::to_string(patch_mm) + ": must be in (0, 10000]");
    }
    if (PatchSpacing(*this) < 8) {
      return fail("image floor: patch_mm = " + std::to_string(patch_mm) + " is " +
                  std::to_string(PatchSpacing(*this)) + " texels of " + std::to_string(mm_per_texel) +
                  " mm; a patch must be at least 8 texels");
    }
  }
  return true;
}

std::unique_ptr<Floor> MakeImageFloor(const ImageFloorOptions& options) {
  std::string why;
  if (!options.Check(&why)) core::ThrowInvalidInput(why);
  const std::string file = options.image.string();
  std::error_code error;
  if (!std::filesystem::is_regular_file(options.image, error)) {
    core::ThrowInvalidInput("image floor: cannot read '" + file + "': no such file");
  }
  cv::Mat decoded;
  try {
    decoded = cv::imread(file, cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception& e) {
    core::ThrowInvalidInput("image floor: cannot read '" + file + "': " + e.what());
  }
  if (decoded.empty()) {
    core::ThrowInvalidInput("image floor: cannot read '" + file +
                            "': unreadable or not an image OpenCV can decode");
  }
  if (decoded.cols < kMinImageSidePx || decoded.rows < kMinImageSidePx) {
    core::ThrowInvalidInput("image floor: '" + file + "' is " + std::to_string(decoded.cols) +
                            " x " + std::to_string(decoded.rows) + " pixels; need at least " +
                            std::to_string(kMinImageSidePx) + " x " +
                            std::to_string(kMinImageSidePx));
  }
  if (options.layout == "repeat") return std::make_unique<ImageFloor>(ToGrey8(decoded), options);
  const int spacing = PatchSpacing(options);
  const int needed = spacing + std::max(2, spacing / 4) + 1;
  if (decoded.cols < needed || decoded.rows < needed) {
    core::ThrowInvalidInput("image floor: '" + file + "' is " + std::to_string(decoded.cols) + " x " +
                            std::to_string(decoded.rows) + " pixels; patches of " +
                            std::to_string(options.patch_mm) + " mm (" + std::to_string(spacing) +
                            " texels) and their blend need at least " + std::to_string(needed) +
                            " x " + std::to_string(needed) + ": choose a smaller patch_mm");
  }
  return std::make_unique<PatchedImageFloor>(ToGrey8(decoded), options, spacing);
}

}  // namespace mosaicloc::sim
