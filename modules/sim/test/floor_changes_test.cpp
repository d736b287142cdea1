#include "mosaicloc/sim/floor_changes.hpp"

#include <gtest/gtest.h>

#include <opencv2/core.hpp>

#include "mosaicloc/core/error.hpp"

namespace mosaicloc::sim {
namespace {

// A coarse procedural floor (1 mm texels): cheap to render over metres.
std::unique_ptr<Floor> Base() {
  ProceduralFloorOptions options;
  options.seed = 4;
  options.mm_per_texel = 1.0;
  return MakeProceduralFloor(options);
}

FloorChangeOptions Everything() {
  FloorChangeOptions o;
  o.seed = 9;
  o.grime_fraction = 0.4;
  o.stains_per_m2 = 5.0;
  o.tyre_marks = 0.6;
  o.wet_x_mm = 300.0;
  o.wet_y_mm = -300.0;
  o.wet_radius_mm = 150.0;
  o.tile_x_mm = 700.0;
  o.tile_y_mm = -700.0;
  o.tile_size_mm = 200.0;
  o.lane_x0_mm = 0.0;
  o.lane_y0_mm = -900.0;
  o.lane_x1_mm = 1000.0;
  o.lane_y1_mm = -900.0;
  o.lane_width_mm = 50.0;
  return o;
}

const std::vector<std::vector<Eigen::Vector2d>> kPaths = {{{0.0, -500.0}, {1000.0, -500.0}}};

// Texel (c, r) at 1 mm: x = c + 0.5, y = -(r + 0.5).
TEST(ChangedFloor, TexelsAreTheSameWhateverTheWindow) {
  const auto floor = ChangedFloor(Base(), Everything(), kPaths);
  const cv::Mat whole = floor->Render(-50, -50, 1100, 1100);
  const cv::Mat part = floor->Render(237, 411, 301, 517);
  EXPECT_EQ(cv::norm(whole(cv::Rect(287, 461, 301, 517)), part, cv::NORM_INF), 0.0);
}

TEST(ChangedFloor, NothingChangedIsTheBase) {
  const auto base = Base();
  const auto floor = ChangedFloor(Base(), FloorChangeOptions{});
  EXPECT_EQ(cv::norm(base->Render(0, 0, 400, 300), floor->Render(0, 0, 400, 300), cv::NORM_INF), 0.0);
}

TEST(ChangedFloor, EachChangeIsWhereItWasPut) {
  FloorChangeOptions o = Everything();
  o.grime_fraction = 0.0;
  o.stains_per_m2 = 0.0;
  const auto floor = ChangedFloor(Base(), o, kPaths);
  const auto base = Base();
  const cv::Mat changed = floor->Render(0, 0, 1000, 1000);
  const cv::Mat before = base->Render(0, 0, 1000, 1000);
  const auto mean_std = [](const cv::Mat& image, const cv::Rect& rect) {
    cv::Scalar mean, std;
    cv::meanStdDev(image(rect), mean, std);
    return std::pair<double, double>(mean[0], std[0]);
  };
  // The wet patch (centre 300, -300): darker and flatter at its heart.
  const cv::Rect wet(270, 270, 60, 60);
  EXPECT_LT(mean_std(changed, wet).first, 0.9 * mean_std(before, wet).first);
  EXPECT_LT(mean_std(changed, wet).second, 0.8 * mean_std(before, wet).second);
  // The replaced tile (600..800): new texture inside, the old one just outside.
  const cv::Rect tile(620, 620, 160, 160);
  EXPECT_GT(cv::norm(changed(tile), before(tile), cv::NORM_L1) / tile.area(), 5.0);
  const cv::Rect beside(810, 620, 40, 160);
  EXPECT_EQ(cv::norm(changed(beside), before(beside), cv::NORM_INF), 0.0);
  // The lane line (y = -900, 50 mm wide): the paint's grey.
  EXPECT_NEAR(mean_std(changed, cv::Rect(100, 890, 800, 20)).first, 230.0, 6.0);
  // The tyre mark (y = -500, 60 mm wide): darker along it.
  const cv::Rect mark(100, 490, 800, 20);
  EXPECT_LT(mean_std(changed, mark).first, 0.8 * mean_std(before, mark).first);
  // Far from everything: untouched.
  const cv::Rect clear(50, 50, 100, 100);
  EXPECT_EQ(cv::norm(changed(clear), before(clear), cv::NORM_INF), 0.0);
}

TEST(ChangedFloor, GrimeCoversTheShareAskedFor) {
  FloorChangeOptions o;
  o.grime_fraction = 0.4;
  o.grime_strength = 1.0;
  const auto floor = ChangedFloor(Base(), o);
  const auto base = Base();
  const cv::Mat changed = floor->Render(0, 0, 1500, 1500);
  const cv::Mat before = base->Render(0, 0, 1500, 1500);
  cv::Mat differs;
  cv::absdiff(changed, before, differs);
  // Texels under the film (not at its soft edge): changed by more than a few counts.
  const double share = cv::countNonZero(differs > 3) / static_cast<double>(differs.total());
  EXPECT_NEAR(share, 0.4, 0.12);
}

TEST(ChangedFloor, BadOptionsAreRefused) {
  FloorChangeOptions o;
  o.grime_fraction = 1.5;
  EXPECT_THROW(ChangedFloor(Base(), o), core::Error);
  o = FloorChangeOptions{};
  o.lane_dn = 300.0;
  std::string why;
  EXPECT_FALSE(o.Check(&why));
  EXPECT_NE(why.find("lane_dn"), std::string::npos);
}

}  // namespace
}  // namespace mosaicloc::sim
