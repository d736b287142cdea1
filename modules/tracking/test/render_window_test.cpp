#include <cmath>
#include <memory>
#include <utility>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "../src/simd.hpp"
#include "mosaicloc/mosaic/tile_store.hpp"
#include "mosaicloc/tracking/render_window.hpp"
#include "tracking_test_support.hpp"

namespace mosaicloc::tracking {
namespace {

TEST(Reference, RenderWindowAtIdentityIsTheImage) {
  cv::Mat image(100, 120, CV_8UC1);
  cv::RNG(7).fill(image, cv::RNG::UNIFORM, 0, 256);
  const ImageReference reference(image, Pose2::Identity(), 1.0);
  Affine identity;
  identity << 1, 0, 0, 0, 1, 0;
  cv::Mat mask;
  const cv::Mat window = RenderWindow(reference, identity, cv::Point(10, 20), cv::Size(50, 40), &mask);
  EXPECT_EQ(cv::norm(window, image(cv::Rect(10, 20, 50, 40)), cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::countNonZero(mask), 50 * 40);
}

// A camera's view of an image placed where that camera took it is the image itself.
TEST(Reference, CameraViewAtTheImagesOwnPoseIsTheImage) {
  const camera::IdealCamera camera{camera::IdealCameraOptions{}};
  cv::Mat image(camera.height_px(), camera.width_px(), CV_8UC1);
  cv::RNG(11).fill(image, cv::RNG::UNIFORM, 0, 256);
  const Pose2 world_from_camera(-40.0, 25.0, 0.0);
  const ImageReference reference(image, world_from_camera, camera.mm_per_px());
  cv::Mat mask;
  const cv::Mat view = RenderCameraView(reference, camera, world_from_camera, &mask);
  // The outermost pixels may fall a rounding error outside the image: unknown there.
  const cv::Rect inner(1, 1, camera.width_px() - 2, camera.height_px() - 2);
  EXPECT_EQ(cv::norm(view(inner), image(inner), cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::countNonZero(mask(inner)), inner.area());
}

// The AVX2 build of the unchecked path (when the processor has it) renders the same pixels
// as the baseline build, at widths that are and are not whole groups of four.
TEST(Reference, RenderWindowVectorBuildsAgreeExactly) {
  cv::Mat image(200, 220, CV_8UC1);
  cv::RNG(13).fill(image, cv::RNG::UNIFORM, 0, 256);
  const ImageReference reference(image, Pose2::Identity(), 1.0);
  Affine frame_to_raster;
  const double c = std::cos(0.7), s = std::sin(0.7);
  frame_to_raster << 0.5 * c, -0.5 * s, 90.3, 0.5 * s, 0.5 * c, 30.7;
  for (const cv::Size size : {cv::Size(60, 60), cv::Size(57, 33)}) {
    const cv::Mat fast = RenderWindow(reference, frame_to_raster, cv::Point(5, 5), size);
    detail::SetAvx2Allowed(false);
    const cv::Mat plain = RenderWindow(reference, frame_to_raster, cv::Point(5, 5), size);
    detail::SetAvx2Allowed(true);
    EXPECT_EQ(cv::norm(fast, plain, cv::NORM_INF), 0.0);
  }
}

// The bilinear value of `image` at raster point r, whose pixel (ix, iy) is the top-left of the four.
double Bilinear(const cv::Mat& image, const Eigen::Vector2d& r, int ix, int iy) {
  const double fx = r.x() - ix, fy = r.y() - iy;
  return (1 - fy) * ((1 - fx) * image.at<std::uint8_t>(iy, ix) + fx * image.at<std::uint8_t>(iy, ix + 1)) +
         fy * ((1 - fx) * image.at<std::uint8_t>(iy + 1, ix) + fx * image.at<std::uint8_t>(iy + 1, ix + 1));
}

// Inside the reference (the unchecked path) and across its edge (the checked one) the window
// is the same bilinear interpolation, rounded, as written out here.
TEST(Reference, RenderWindowIsBilinearInsideAndAcrossTheEdge) {
  cv::Mat image(200, 220, CV_8UC1);
  cv::RNG(11).fill(image, cv::RNG::UNIFORM, 0, 256);
  const ImageReference reference(image, Pose2::Identity(), 1.0);
  Affine frame_to_raster;
  const double c = std::cos(0.3), s = std::sin(0.3);
  frame_to_raster << 0.9 * c, -0.9 * s, 60.3, 0.9 * s, 0.9 * c, 20.7;
  // Known pixels, and how many pixels differ from the expectation.
  const auto compare = [&](const cv::Point& origin, const cv::Size& size) {
    cv::Mat mask;
    const cv::Mat window = RenderWindow(reference, frame_to_raster, origin, size, &mask);
    int known = 0, wrong = 0;
    for (int y = 0; y < size.height; ++y) {
      for (int x = 0; x < size.width; ++x) {
        const Eigen::Vector2d r = ApplyAffine(frame_to_raster, Eigen::Vector2d(origin.x + x, origin.y + y));
        const int ix = static_cast<int>(std::floor(r.x())), iy = static_cast<int>(std::floor(r.y()));
        const bool inside = ix >= 0 && iy >= 0 && ix + 1 < image.cols && iy + 1 < image.rows;
        wrong += mask.at<std::uint8_t>(y, x) != (inside ? 255 : 0) ? 1 : 0;
        if (!inside) continue;
        ++known;
        wrong += std::abs(window.at<std::uint8_t>(y, x) - Bilinear(image, r, ix, iy)) > 0.5 + 1e-9 ? 1 : 0;
      }
    }
    return std::pair<int, int>(known, wrong);
  };
  const auto [inside_known, inside_wrong] = compare(cv::Point(10, 10), cv::Size(70, 60));
  EXPECT_EQ(inside_known, 70 * 60);
  EXPECT_EQ(inside_wrong, 0);
  const auto [edge_known, edge_wrong] = compare(cv::Point(-80, 40), cv::Size(90, 90));
  EXPECT_GT(edge_known, 0);
  EXPECT_LT(edge_known, 90 * 90);
  EXPECT_EQ(edge_wrong, 0);
}

// An image whose known pixels are given by a mask (a map's holes and edges), for windows
// that cross unmapped floor inside their block.
class MaskedReference : public ReferenceRaster {
 public:
  MaskedReference(cv::Mat image, cv::Mat mask) : image_(std::move(image)), mask_(std::move(mask)) {}
  Eigen::Matrix<double, 2, 3> RasterToWorld() const override {
    Eigen::Matrix<double, 2, 3> a;
    a << 1, 0, 0, 0, 1, 0;
    return a;
  }
  void Region(std::int64_t col0, std::int64_t row0, int cols, int rows, cv::Mat& store,
              mosaic::RasterPatch* patch) const override {
    // The tests' windows stay inside the image.
    const cv::Rect rect(static_cast<int>(col0), static_cast<int>(row0), cols, rows);
    store = image_(rect).clone();
    patch->image = store;
    patch->mask = mask_(rect).clone();
    patch->col0 = col0;
    patch->row0 = row0;
    patch->all_mapped = cv::countNonZero(patch->mask) == cols * rows;
    if (patch->all_mapped) patch->mask.release();
  }
  std::unique_ptr<const ReferenceRaster> Coarser() const override { return nullptr; }

 private:
  cv::Mat image_, mask_;
};

// A window over a block that is partly unmapped (holes, an edge) knows exactly the pixels whose
// four bilinear sources are all mapped, shows the bilinear value there and unmapped elsewhere,
// in both builds of the loop.
TEST(Reference, RenderWindowOverHolesKnowsExactlyTheSamplesWithFourMappedSources) {
  cv::Mat image(200, 220, CV_8UC1);
  cv::RNG(17).fill(image, cv::RNG::UNIFORM, 1, 256);
  cv::Mat known(image.size(), CV_8UC1, cv::Scalar(255));
  cv::circle(known, cv::Point(100, 90), 17, cv::Scalar(0), cv::FILLED);
  known(cv::Rect(0, 150, 220, 50)).setTo(cv::Scalar(0));
  known.at<std::uint8_t>(60, 70) = 0;
  const MaskedReference reference(image, known);
  Affine frame_to_raster;
  const double c = std::cos(0.4), s = std::sin(0.4);
  frame_to_raster << 0.8 * c, -0.8 * s, 70.3, 0.8 * s, 0.8 * c, 20.6;
  const cv::Point origin(5, 7);
  for (const cv::Size size : {cv::Size(120, 130), cv::Size(117, 129)}) {
    cv::Mat mask;
    const cv::Mat window = RenderWindow(reference, frame_to_raster, origin, size, &mask);
    int mapped = 0, wrong = 0;
    for (int y = 0; y < size.height; ++y) {
      for (int x = 0; x < size.width; ++x) {
        const Eigen::Vector2d r = ApplyAffine(frame_to_raster, Eigen::Vector2d(origin.x + x, origin.y + y));
        const int ix = static_cast<int>(std::floor(r.x())), iy = static_cast<int>(std::floor(r.y()));
        const bool four = known.at<std::uint8_t>(iy, ix) != 0 && known.at<std::uint8_t>(iy, ix + 1) != 0 &&
                          known.at<std::uint8_t>(iy + 1, ix) != 0 && known.at<std::uint8_t>(iy + 1, ix + 1) != 0;
        wrong += mask.at<std::uint8_t>(y, x) != (four ? 255 : 0) ? 1 : 0;
        if (!four) {
          wrong += window.at<std::uint8_t>(y, x) != mosaic::kUnmapped ? 1 : 0;
          continue;
        }
        ++mapped;
        wrong += std::abs(window.at<std::uint8_t>(y, x) - Bilinear(image, r, ix, iy)) > 0.5 + 1e-9 ? 1 : 0;
      }
    }
    EXPECT_GT(mapped, size.area() / 2);
    EXPECT_LT(mapped, size.area() - 500);
    EXPECT_EQ(wrong, 0);
    detail::SetAvx2Allowed(false);
    cv::Mat plain_mask;
    const cv::Mat plain = RenderWindow(reference, frame_to_raster, origin, size, &plain_mask);
    detail::SetAvx2Allowed(true);
    EXPECT_EQ(cv::norm(window, plain, cv::NORM_INF), 0.0);
    EXPECT_EQ(cv::norm(mask, plain_mask, cv::NORM_INF), 0.0);
  }
}

}  // namespace
}  // namespace mosaicloc::tracking
