#include "mosaicloc/runtime/registration_bench.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <fmt/printf.h>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/core/log.hpp"
#include "mosaicloc/core/pose2.hpp"
#include "mosaicloc/dataset/evaluation.hpp"
#include "mosaicloc/sim/resample.hpp"
#include "mosaicloc/tracking/tracker.hpp"

namespace mosaicloc::runtime {
namespace {


using Affine = Eigen::Matrix<double, 2, 3>;
constexpr double kDeg = std::numbers::pi / 180.0;
constexpr double kMmPerPx = 0.25;

// A registration pair: a reference image and a live image of the same floor, related by
//   reference pixel = R(theta) (live pixel - c) + c + d   (image axes, c the image centre),
// rendered with exact positions from a real texture at half its resolution.
struct Pair {
  cv::Mat reference;
  cv::Mat live;
  double theta_rad = 0.0;
  Eigen::Vector2d d = Eigen::Vector2d::Zero();
};

// The live image as its camera delivers it: another gain and offset, sensor noise, 8 bits.
cv::Mat AsSensed(const cv::Mat& image, const RegistrationBenchOptions& o, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  const double gain = 1.0 + unit(rng) * o.max_gain_change;
  const double offset = unit(rng) * o.max_offset_dn;
  cv::Mat live = image * gain + offset;
  cv::Mat noise(image.size(), CV_32FC1);
  cv::RNG cv_rng(rng());
  cv_rng.fill(noise, cv::RNG::NORMAL, 0.0, o.noise_dn);
  live += noise;
  cv::Mat out;
  live.convertTo(out, CV_8UC1);
  return out;
}

Pair MakePair(const cv::Mat& texture, double scale, cv::Size size, const RegistrationBenchOptions& o, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  Pair pair;
  pair.theta_rad = unit(rng) * o.max_rotation_deg * kDeg;
  pair.d = {unit(rng) * o.max_shift_px, unit(rng) * o.max_shift_px};
  // Where the reference sits in the texture (`scale` texture pixels per image pixel), with
  // room for the live view's rotation and shift.
  const double margin =
      scale * (o.max_shift_px + 0.5 * std::hypot(size.width, size.height) * std::sin(o.max_rotation_deg * kDeg) + 8.0);
  std::uniform_real_distribution<double> ox(margin, texture.cols - scale * size.width - margin);
  std::uniform_real_distribution<double> oy(margin, texture.rows - scale * size.height - margin);
  Affine source_from_reference;
  source_from_reference << scale, 0.0, ox(rng), 0.0, scale, oy(rng);
  const Eigen::Vector2d c(0.5 * (size.width - 1), 0.5 * (size.height - 1));
  Affine reference_from_live;
  reference_from_live.leftCols<2>() << std::cos(pair.theta_rad), -std::sin(pair.theta_rad), std::sin(pair.theta_rad),
      std::cos(pair.theta_rad);
  reference_from_live.col(2) = c + pair.d - reference_from_live.leftCols<2>() * c;

  sim::ResampleExact(texture, source_from_reference, size, 2).convertTo(pair.reference, CV_8UC1);
  cv::Mat live =
      sim::ResampleExact(texture, tracking::ComposeAffine(source_from_reference, reference_from_live), size, 2);
  pair.live = AsSensed(live, o, rng);
  return pair;
}

// A pair whose live view is a pinhole's at (1 + dk) times the height, tilted by (a, b) about
// its x and y axes and turned by theta, over the floor point at reference pixel c + d: each
// pixel is a ray cast onto the floor (exact, on a twice finer grid, area-averaged), the
// reference rendered the same way straight down.
Pair MakePerspectivePair(const cv::Mat& texture, double scale, cv::Size size, const RegistrationBenchOptions& o,
                         std::mt19937_64& rng) {
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  Pair pair;
  pair.theta_rad = unit(rng) * o.max_rotation_deg * kDeg;
  pair.d = {unit(rng) * o.max_shift_px, unit(rng) * o.max_shift_px};
  const double k = 1.0 + unit(rng) * o.max_scale_change;
  const double a = unit(rng) * o.max_tilt_deg * kDeg, b = unit(rng) * o.max_tilt_deg * kDeg;
  const double f = 800.0;  // the focal length in pixels: 200 mm over 0.25 mm/px
  const Eigen::Vector2d c(0.5 * (size.width - 1), 0.5 * (size.height - 1));
  const double margin = scale * (o.max_shift_px + 0.5 * std::hypot(size.width, size.height) *
                                                      (std::sin(o.max_rotation_deg * kDeg) + o.max_scale_change +
                                                       2.0 * std::tan(o.max_tilt_deg * kDeg)) + 12.0);
  std::uniform_real_distribution<double> ox(margin, texture.cols - scale * size.width - margin);
  std::uniform_real_distribution<double> oy(margin, texture.rows - scale * size.height - margin);
  const Eigen::Vector2d origin(ox(rng), oy(rng));
  // Reference pixel q <-> floor point ((q - c)_x, -(q - c)_y) in pixels of the reference.
  // Image axes have y down: a turn by theta in the image is -theta on the floor.
  const Eigen::Matrix3d rotation = (Eigen::AngleAxisd(-pair.theta_rad, Eigen::Vector3d::UnitZ()) *
                                    Eigen::AngleAxisd(a, Eigen::Vector3d::UnitX()) *
                                    Eigen::AngleAxisd(b, Eigen::Vector3d::UnitY()))
                                       .toRotationMatrix();
  // The lens: over the floor point d (image axes, y down) less the tilt's offset of the centre ray.
  const Eigen::Vector3d centre_ray = rotation * Eigen::Vector3d(0.0, 0.0, -1.0);
  const Eigen::Vector2d d_floor(pair.d.x(), -pair.d.y());
  const Eigen::Vector2d lens = d_floor - k * f * centre_ray.head<2>() / -centre_ray.z();
  const auto render = [&](bool live) {
    const int n = 2;
    cv::Mat map_x(size.height * n, size.width * n, CV_32F), map_y(size.height * n, size.width * n, CV_32F);
    for (int v = 0; v < map_x.rows; ++v) {
      for (int u = 0; u < map_x.cols; ++u) {
        const Eigen::Vector2d p((u + 0.5) / n - 0.5, (v + 0.5) / n - 0.5);
        Eigen::Vector2d floor(p.x() - c.x(), -(p.y() - c.y()));
        if (live) {
          const Eigen::Vector3d ray = rotation * Eigen::Vector3d(floor.x() / f, floor.y() / f, -1.0);
          floor = lens + k * f * ray.head<2>() / -ray.z();
        }
        const Eigen::Vector2d q(floor.x() + c.x(), -floor.y() + c.y());
        map_x.at<float>(v, u) = static_cast<float>(origin.x() + scale * (q.x() + 0.5) - 0.5);
        map_y.at<float>(v, u) = static_cast<float>(origin.y() + scale * (q.y() + 0.5) - 0.5);
      }
    }
    cv::Mat fine, image;
    cv::remap(texture, fine, map_x, map_y, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
    fine.convertTo(fine, CV_32F);
    cv::resize(fine, image, size, 0, 0, cv::INTER_AREA);
    return image;
  };
  render(false).convertTo(pair.reference, CV_8UC1);
  cv::Mat live = render(true);
  pair.live = AsSensed(live, o, rng);
  return pair;
}

// What a method says: reference pixel = R(theta) (live pixel - c) + c + d, or nothing.
struct Estimate {
  bool ok = false;
  double theta_rad = 0.0;
  Eigen::Vector2d d = Eigen::Vector2d::Zero();
};

struct Method {
  std::string key;  ///< for --methods
  std::string name;
  std::function<Estimate(const Pair&)> run;
  std::vector<double> error_px, error_deg, time_ms;
  int failures = 0;
};

// Estimate from a 2x3 affine live pixel -> reference pixel.
Estimate FromAffine(const Affine& reference_from_live, const Eigen::Vector2d& c) {
  Estimate e;
  e.ok = reference_from_live.allFinite();
  e.theta_rad = std::atan2(reference_from_live(1, 0), reference_from_live(0, 0));
  e.d = reference_from_live.leftCols<2>() * c + reference_from_live.col(2) - c;
  return e;
}

double Rms(const std::vector<double>& v) {
  if (v.empty()) return std::nan("");
  double s = 0.0;
  for (const double x : v) s += x * x;
  return std::sqrt(s / static_cast<double>(v.size()));
}

double Max(const std::vector<double>& v) { return v.empty() ? std::nan("") : *std::max_element(v.begin(), v.end()); }

double Mean(const std::vector<double>& v) {
  if (v.empty()) return std::nan("");
  double s = 0.0;
  for (const double x : v) s += x;
  return s / static_cast<double>(v.size());
}

double P50(std::vector<double> v) {
  if (v.empty()) return std::nan("");
  std::sort(v.begin(), v.end());
  return dataset::Percentile(v, 50.0);
}

// OpenCV's ECC over the whole frame with `motion` (MOTION_EUCLIDEAN or MOTION_HOMOGRAPHY). Its
// warp maps reference pixels to live pixels: the estimate is where the live image centre lies
// in the reference, and the direction of the live x axis there.
Estimate Ecc(const Pair& pair, int motion, const Eigen::Vector2d& c) {
  cv::Mat warp = cv::Mat::eye(motion == cv::MOTION_HOMOGRAPHY ? 3 : 2, 3, CV_32F);
  try {
    cv::findTransformECC(pair.reference, pair.live, warp, motion,
                         cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 100, 1e-6), cv::noArray(),
                         5);
  } catch (const cv::Exception&) {
    return Estimate{};
  }
  Eigen::Matrix3d live_from_reference = Eigen::Matrix3d::Identity();
  for (int r = 0; r < warp.rows; ++r) {
    for (int k = 0; k < 3; ++k) live_from_reference(r, k) = warp.at<float>(r, k);
  }
  const Eigen::Matrix3d reference_from_live = live_from_reference.inverse();
  const auto map = [&](const Eigen::Vector2d& p) {
    const Eigen::Vector3d h = reference_from_live * p.homogeneous();
    return Eigen::Vector2d(h.head<2>() / h.z());
  };
  Estimate e;
  e.ok = reference_from_live.allFinite();
  const Eigen::Vector2d centre = map(c);
  const Eigen::Vector2d along = map(c + Eigen::Vector2d(1.0, 0.0)) - centre;
  e.theta_rad = std::atan2(along.y(), along.x());
  e.d = centre - c;
  return e;
}

std::vector<Method> MakeMethods(const camera::IdealCamera& camera) {
  const Eigen::Vector2d c(camera.cx(), camera.cy());
  std::vector<Method> methods;
  // The prior our tracker gets: identity, with the offsets' spread as its uncertainty.
  const Eigen::Matrix3d prior = Eigen::Vector3d(std::pow(8.0 / 3.0 * kMmPerPx, 2), std::pow(8.0 / 3.0 * kMmPerPx, 2),
                                                std::pow(1.0 * kDeg, 2))
                                    .asDiagonal();
  auto ours = [&camera, c, prior](const tracking::TrackerOptions& options) {
    auto tracker = std::make_shared<tracking::Tracker>(camera, options);
    return [tracker, &camera, c, prior](const Pair& pair) {
      const tracking::ImageReference reference(pair.reference, core::Pose2::Identity(), kMmPerPx);
      const tracking::TrackResult r = tracker->Track(pair.live, core::Pose2::Identity(), prior, reference);
      if (!r.ok()) {
        std::string detail;
        for (const tracking::TemplateReport& t : r.templates) {
          detail += " [" + std::to_string(t.spot.rect.x) + "," + std::to_string(t.spot.rect.y) + " peak " +
                    std::to_string(t.coarse.peak) + " ambiguity " + std::to_string(t.coarse.ambiguity) + " zncc " +
                    std::to_string(t.refined.zncc) + " " + (t.rejected.empty() ? "used" : t.rejected) + "]";
        }
        core::Log().debug("tracker declined a pair: {}:{}", r.reason, detail);
        return Estimate{};
      }
      const Affine world_from_live = camera.PixelToWorldAffine(r.world_from_camera);
      return FromAffine(tracking::ComposeAffine(reference.WorldToRaster(), world_from_live), c);
    };
  };
  tracking::TrackerOptions defaults;
  methods.push_back({"ours", "mosaicloc 4x96 (default)", ours(defaults), {}, {}, {}, 0});
  tracking::TrackerOptions nine = defaults;
  nine.templates.count = 9;
  nine.templates.size_px = 128;
  methods.push_back({"ours-9x128", "mosaicloc 9x128", ours(nine), {}, {}, {}, 0});
  tracking::TrackerOptions tiled = defaults;
  tiled.templates.mode = tracking::TemplateMode::kTiled;
  methods.push_back({"ours-tiled", "mosaicloc whole frame (4x3 tiles)", ours(tiled), {}, {}, {}, 0});
  tracking::TrackerOptions tilt = defaults;
  tilt.templates.count = 12;
  tilt.solver.estimate_tilt = true;
  methods.push_back({"ours-tilt", "mosaicloc 12x96, scale and tilt estimated", ours(tilt), {}, {}, {}, 0});
  tracking::TrackerOptions observer = defaults;
  observer.solver.method = tracking::PoseMethod::kKalmanObserver;
  methods.push_back({"ours-observer", "mosaicloc 4x96, the paper's Kalman observer", ours(observer), {}, {}, {}, 0});
  tracking::TrackerOptions visp = defaults;
  visp.refine.method = tracking::RefineMethod::kVispZncc;
  visp.refine.warp = tracking::RefineWarp::kSrt;
  methods.push_back({"ours-visp", "mosaicloc 4x96, ViSP ZNCC-IC SRT refine", ours(visp), {}, {}, {}, 0});

  methods.push_back({"ecc", "OpenCV findTransformECC (euclidean, full frame)",
                     [c](const Pair& pair) { return Ecc(pair, cv::MOTION_EUCLIDEAN, c); }, {}, {}, {}, 0});
  methods.push_back({"ecc-homography", "OpenCV findTransformECC (homography, full frame)",
                     [c](const Pair& pair) { return Ecc(pair, cv::MOTION_HOMOGRAPHY, c); }, {}, {}, {}, 0});
  methods.push_back({"phase", "OpenCV phaseCorrelate (translation)",
                     [c](const Pair& pair) {
                       cv::Mat a, b, window;
                       pair.reference.convertTo(a, CV_64F);
                       pair.live.convertTo(b, CV_64F);
                       cv::createHanningWindow(window, a.size(), CV_64F);
                       const cv::Point2d shift = cv::phaseCorrelate(a, b, window);
                       // live(x) = reference(x - shift): reference pixel = live pixel - shift.
                       Affine reference_from_live;
                       reference_from_live << 1.0, 0.0, -shift.x, 0.0, 1.0, -shift.y;
                       return FromAffine(reference_from_live, c);
                     },
                     {}, {}, {}, 0});
  methods.push_back({"visp", "ViSP ZNCC-IC SRT alone (256x256 zone, pyramid)",
                     [c](const Pair& pair) {
                       const tracking::ImageReference reference(pair.reference, core::Pose2::Identity(), 1.0);
                       tracking::RefineOptions options;
                       options.method = tracking::RefineMethod::kVispZncc;
                       options.warp = tracking::RefineWarp::kSrt;
                       options.visp_pyramid_levels = 2;
                       options.max_shift_px = 16.0;
                       options.max_iterations = 30;
                       const cv::Rect zone(static_cast<int>(c.x()) - 127, static_cast<int>(c.y()) - 127, 256, 256);
                       Affine identity;
                       identity << 1, 0, 0, 0, 1, 0;
                       const tracking::RefinedMatch m =
                           tracking::RefineTemplate(pair.live, zone, reference, identity, options);
                       if (!m.ok()) return Estimate{};
                       Estimate e;
                       e.ok = true;
                       e.theta_rad = m.rotation_rad;
                       // The zone is centred on the image centre (to half a pixel).
                       const Eigen::Vector2d zone_centre(zone.x + 127.5, zone.y + 127.5);
                       e.d = m.centre_raster - zone_centre;  // the zone is centred on c
                       return e;
                     },
                     {}, {}, {}, 0});
  return methods;
}

}  // namespace

bool RegistrationBenchOptions::Check(std::string* why) const {
  if (textures.empty()) {
    *why = "registration bench: no texture";
    return false;
  }
  if (pairs < 1 || pairs > 100000) {
    *why = "registration bench: pairs must be in [1, 100000]";
    return false;
  }
  if (!(max_shift_px >= 0.0 && max_shift_px <= 32.0) || !(max_rotation_deg >= 0.0 && max_rotation_deg <= 10.0) ||
      !(noise_dn >= 0.0 && noise_dn <= 50.0)) {
    *why = "registration bench: shifts up to 32 px, rotations up to 10 deg and noise up to 50 DN";
    return false;
  }
  if (!(max_scale_change >= 0.0 && max_scale_change <= 0.2) || !(max_tilt_deg >= 0.0 && max_tilt_deg <= 10.0)) {
    *why = "registration bench: scale changes up to 0.2 and tilts up to 10 deg";
    return false;
  }
  for (const std::string& key : methods) {
    if (std::find(RegistrationBenchMethods().begin(), RegistrationBenchMethods().end(), key) ==
        RegistrationBenchMethods().end()) {
      *why = "registration bench: no method '" + key + "'";
      return false;
    }
  }
  return true;
}

const std::vector<std::string>& RegistrationBenchMethods() {
  static const std::vector<std::string> keys = {"ours",          "ours-9x128", "ours-tiled",     "ours-visp",
                                                "ours-tilt",     "ours-observer", "ecc", "ecc-homography",
                                                "phase",         "visp"};
  return keys;
}

std::vector<RegistrationBenchRow> RunRegistrationBench(const RegistrationBenchOptions& options,
                                                       const std::function<void(double)>& progress) {
  std::string why;
  if (!options.Check(&why)) core::ThrowInvalidInput(why);
  cv::setNumThreads(1);  // every method on one core
  const camera::IdealCamera camera{camera::IdealCameraOptions{}};
  const cv::Size size(camera.width_px(), camera.height_px());
  std::vector<Method> methods = MakeMethods(camera);
  if (!options.methods.empty()) {
    std::erase_if(methods, [&](const Method& m) {
      return std::find(options.methods.begin(), options.methods.end(), m.key) == options.methods.end();
    });
  }
  std::mt19937_64 rng(options.seed);
  const std::int64_t total = static_cast<std::int64_t>(options.textures.size()) * options.pairs;
  std::int64_t done = 0;
  for (const std::filesystem::path& file : options.textures) {
    const cv::Mat texture = cv::imread(file.string(), cv::IMREAD_GRAYSCALE);
    if (texture.empty()) core::ThrowInvalidInput(file.string() + ": not an image OpenCV can read");
    // Pairs are cut at half the texture's resolution when it is large enough (a camera
    // averaging a finer floor), else at its own.
    const double scale = texture.cols >= 2 * size.width + 200 && texture.rows >= 2 * size.height + 200 ? 2.0 : 1.0;
    if (texture.cols < size.width + 100 || texture.rows < size.height + 100) {
      core::ThrowInvalidInput(file.string() + ": texture too small; need at least " +
                              std::to_string(size.width + 100) + "x" + std::to_string(size.height + 100) + " pixels");
    }
    for (int i = 0; i < options.pairs; ++i) {
      const bool perspective = options.max_scale_change > 0.0 || options.max_tilt_deg > 0.0;
      const Pair pair = perspective ? MakePerspectivePair(texture, scale, size, options, rng)
                                    : MakePair(texture, scale, size, options, rng);
      for (Method& method : methods) {
        const auto start = std::chrono::steady_clock::now();
        const Estimate e = method.run(pair);
        method.time_ms.push_back(
            std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count());
        const double error_px = (e.d - pair.d).norm();
        const double error_deg = std::abs(core::WrapAngle(e.theta_rad - pair.theta_rad)) / kDeg;
        if (!e.ok || !(error_px <= options.failure_px) || !(error_deg <= options.failure_deg)) {
          ++method.failures;
          continue;
        }
        method.error_px.push_back(error_px);
        method.error_deg.push_back(error_deg);
      }
      ++done;
      if (progress) progress(static_cast<double>(done) / static_cast<double>(total));
    }
  }

  double ecc_ms = std::nan("");
  for (const Method& m : methods) {
    if (m.key == "ecc") ecc_ms = Mean(m.time_ms);
  }
  std::vector<RegistrationBenchRow> rows;
  for (const Method& m : methods) {
    const double n = static_cast<double>(m.time_ms.size());
    rows.push_back({m.name, m.time_ms.size(), m.failures / n, Rms(m.error_px), Max(m.error_px), Rms(m.error_deg),
                    Max(m.error_deg), Mean(m.time_ms), P50(m.time_ms), Mean(m.time_ms) / ecc_ms});
  }
  return rows;
}

nlohmann::json RegistrationBenchJson(const std::vector<RegistrationBenchRow>& rows) {
  nlohmann::json out = nlohmann::json::array();
  const auto number = [](double value) { return std::isnan(value) ? nlohmann::json() : nlohmann::json(value); };
  for (const RegistrationBenchRow& r : rows) {
    out.push_back({{"method", r.method}, {"pairs", r.pairs}, {"failure_rate", number(r.failure_rate)},
                   {"rms_px", number(r.rms_px)}, {"max_px", number(r.max_px)}, {"rms_deg", number(r.rms_deg)},
                   {"max_deg", number(r.max_deg)}, {"mean_ms", number(r.mean_ms)}, {"p50_ms", number(r.p50_ms)},
                   {"time_vs_ecc", number(r.time_vs_ecc)}});
  }
  return out;
}

std::string RegistrationBenchText(const RegistrationBenchOptions& o, const std::vector<RegistrationBenchRow>& rows) {
  std::string out = fmt::sprintf(
      "%d texture(s) x %d pairs, 640x480, offsets up to +-%.1f px and +-%.1f deg, height +-%.1f %%, tilt +-%.2f deg, "
      "noise %.1f DN, gain +-%.0f %%, offset +-%.0f DN; failure = error > %.2f px or %.2f deg; one core\n\n",
      static_cast<int>(o.textures.size()), o.pairs, o.max_shift_px, o.max_rotation_deg, 100.0 * o.max_scale_change,
      o.max_tilt_deg, o.noise_dn, 100.0 * o.max_gain_change, o.max_offset_dn, o.failure_px, o.failure_deg);
  out += fmt::sprintf("%-48s %8s %9s %9s %9s %9s %9s %9s %9s\n", "method", "failures", "rms px", "max px", "rms deg",
                      "max deg", "mean ms", "p50 ms", "vs ECC");
  for (const RegistrationBenchRow& r : rows) {
    out += fmt::sprintf("%-48s %7.1f%% %9.4f %9.4f %9.4f %9.4f %9.2f %9.2f %8.2f%%\n", r.method, 100.0 * r.failure_rate,
                        r.rms_px, r.max_px, r.rms_deg, r.max_deg, r.mean_ms, r.p50_ms, 100.0 * r.time_vs_ecc);
  }
  return out;
}

}  // namespace mosaicloc::runtime
