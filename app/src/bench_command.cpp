// mosaicloc bench registration: our registration against its peers on the same pairs, in one
// run, on one core.
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

#include <Eigen/LU>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>

#include "commands.hpp"
#include "mosaicloc/core/error.hpp"
#include "mosaicloc/core/log.hpp"
#include "mosaicloc/dataset/evaluation.hpp"
#include "mosaicloc/sim/resample.hpp"
#include "mosaicloc/tracking/tracker.hpp"
#include "progress.hpp"

namespace mosaicloc::app {
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

struct PairOptions {
  double max_shift_px = 8.0;
  double max_rotation_deg = 3.0;
  double noise_dn = 2.0;
  double max_gain_change = 0.15;
  double max_offset_dn = 15.0;
};

Pair MakePair(const cv::Mat& texture, double scale, cv::Size size, const PairOptions& o, std::mt19937_64& rng) {
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
  const double gain = 1.0 + unit(rng) * o.max_gain_change;
  const double offset = unit(rng) * o.max_offset_dn;
  live = live * gain + offset;
  cv::Mat noise(size, CV_32FC1);
  cv::RNG cv_rng(rng());
  cv_rng.fill(noise, cv::RNG::NORMAL, 0.0, o.noise_dn);
  live += noise;
  live.convertTo(pair.live, CV_8UC1);
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

Affine Invert(const Affine& a) {
  Affine r;
  r.leftCols<2>() = a.leftCols<2>().inverse();
  r.col(2) = -r.leftCols<2>() * a.col(2);
  return r;
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
  tracking::TrackerOptions visp = defaults;
  visp.refine.method = tracking::RefineMethod::kVispZncc;
  visp.refine.warp = tracking::RefineWarp::kSrt;
  methods.push_back({"ours-visp", "mosaicloc 4x96, ViSP ZNCC-IC SRT refine", ours(visp), {}, {}, {}, 0});

  methods.push_back({"ecc", "OpenCV findTransformECC (euclidean, full frame)",
                     [c](const Pair& pair) {
                       cv::Mat warp = cv::Mat::eye(2, 3, CV_32F);
                       try {
                         cv::findTransformECC(
                             pair.reference, pair.live, warp, cv::MOTION_EUCLIDEAN,
                             cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 100, 1e-6),
                             cv::noArray(), 5);
                       } catch (const cv::Exception&) {
                         return Estimate{};
                       }
                       // ECC's warp maps reference pixels to live pixels.
                       Affine live_from_reference;
                       for (int r = 0; r < 2; ++r) {
                         for (int k = 0; k < 3; ++k) live_from_reference(r, k) = warp.at<float>(r, k);
                       }
                       return FromAffine(Invert(live_from_reference), c);
                     },
                     {}, {}, {}, 0});
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

Action AddBenchCommand(CLI::App& app, const GlobalOptions& global) {
  struct Args {
    std::vector<std::filesystem::path> textures;
    int pairs = 50;
    std::uint64_t seed = 1;
    PairOptions pair;
    double failure_px = 1.0;
    double failure_deg = 0.1;
    std::vector<std::string> methods;
  };
  auto args = std::make_shared<Args>();
  CLI::App* bench = app.add_subcommand("bench", "Benchmarks that print figures (never pass/fail)");
  bench->require_subcommand(1);
  CLI::App* registration = bench->add_subcommand(
      "registration", "Register 640x480 pairs cut from real textures with mosaicloc and its peers; print the table");
  registration->add_option("--texture", args->textures, "Texture image(s), e.g. ../shared/data/textures/*")
      ->required()
      ->check(CLI::ExistingFile);
  registration->add_option("--pairs", args->pairs, "Pairs per texture")
      ->capture_default_str()
      ->check(CLI::Range(1, 100000));
  registration->add_option("--seed", args->seed, "Random seed")->capture_default_str();
  registration->add_option("--max-shift-px", args->pair.max_shift_px, "Largest offset along each axis, px")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 32.0));
  registration->add_option("--max-rotation-deg", args->pair.max_rotation_deg, "Largest rotation, degrees")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 10.0));
  registration->add_option("--noise", args->pair.noise_dn, "Sensor noise standard deviation, DN")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 50.0));
  registration->add_option("--methods", args->methods,
                           "Only these: ours, ours-9x128, ours-tiled, ours-visp, ecc, phase, visp (default all)")
      ->delimiter(',')
      ->check(CLI::IsMember({"ours", "ours-9x128", "ours-tiled", "ours-visp", "ecc", "phase", "visp"}));
  registration->add_option("--failure-px", args->failure_px, "An error above this (px at the centre) is a failure")
      ->capture_default_str();
  registration->add_option("--failure-deg", args->failure_deg, "A rotation error above this is a failure")
      ->capture_default_str();

  return [args, &global] {
    cv::setNumThreads(1);  // every method on one core
    const camera::IdealCamera camera{camera::IdealCameraOptions{}};
    const cv::Size size(camera.width_px(), camera.height_px());
    std::vector<Method> methods = MakeMethods(camera);
    if (!args->methods.empty()) {
      std::erase_if(methods, [&](const Method& m) {
        return std::find(args->methods.begin(), args->methods.end(), m.key) == args->methods.end();
      });
    }
    std::mt19937_64 rng(args->seed);
    const std::int64_t total = static_cast<std::int64_t>(args->textures.size()) * args->pairs;
    ProgressBar progress("registering pairs", global.quiet || global.json);
    std::int64_t done = 0;
    for (const std::filesystem::path& file : args->textures) {
      const cv::Mat texture = cv::imread(file.string(), cv::IMREAD_GRAYSCALE);
      if (texture.empty()) core::ThrowInvalidInput(file.string() + ": not an image OpenCV can read");
      // Pairs are cut at half the texture's resolution when it is large enough (a camera
      // averaging a finer floor), else at its own.
      const double scale = texture.cols >= 2 * size.width + 200 && texture.rows >= 2 * size.height + 200 ? 2.0 : 1.0;
      if (texture.cols < size.width + 100 || texture.rows < size.height + 100) {
        core::ThrowInvalidInput(file.string() + ": texture too small; need at least " +
                                std::to_string(size.width + 100) + "x" + std::to_string(size.height + 100) + " pixels");
      }
      for (int i = 0; i < args->pairs; ++i) {
        const Pair pair = MakePair(texture, scale, size, args->pair, rng);
        for (Method& method : methods) {
          const auto start = std::chrono::steady_clock::now();
          const Estimate e = method.run(pair);
          method.time_ms.push_back(
              std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count());
          const double error_px = (e.d - pair.d).norm();
          const double error_deg = std::abs(core::WrapAngle(e.theta_rad - pair.theta_rad)) / kDeg;
          if (!e.ok || !(error_px <= args->failure_px) || !(error_deg <= args->failure_deg)) {
            ++method.failures;
            continue;
          }
          method.error_px.push_back(error_px);
          method.error_deg.push_back(error_deg);
        }
        progress.Update(static_cast<double>(++done) / static_cast<double>(total));
      }
    }
    progress.Finish();

    double ecc_ms = std::nan("");
    for (const Method& m : methods) {
      if (m.key == "ecc") ecc_ms = Mean(m.time_ms);
    }
    nlohmann::json out = nlohmann::json::array();
    for (const Method& m : methods) {
      const double n = static_cast<double>(m.time_ms.size());
      out.push_back({{"method", m.name},
                     {"pairs", m.time_ms.size()},
                     {"failure_rate", m.failures / n},
                     {"rms_px", Rms(m.error_px)},
                     {"max_px", Max(m.error_px)},
                     {"rms_deg", Rms(m.error_deg)},
                     {"max_deg", Max(m.error_deg)},
                     {"mean_ms", Mean(m.time_ms)},
                     {"p50_ms", P50(m.time_ms)},
                     {"time_vs_ecc", Mean(m.time_ms) / ecc_ms}});
    }
    if (global.json) {
      std::printf("%s\n", out.dump(2).c_str());
      return;
    }
    std::printf("%zu texture(s) x %d pairs, 640x480, offsets up to +-%.1f px and +-%.1f deg, noise %.1f DN, "
                "gain +-%.0f %%, offset +-%.0f DN; failure = error > %.2f px or %.2f deg; one core\n\n",
                args->textures.size(), args->pairs, args->pair.max_shift_px, args->pair.max_rotation_deg,
                args->pair.noise_dn, 100.0 * args->pair.max_gain_change, args->pair.max_offset_dn, args->failure_px,
                args->failure_deg);
    std::printf("%-48s %8s %9s %9s %9s %9s %9s %9s %9s\n", "method", "failures", "rms px", "max px", "rms deg",
                "max deg", "mean ms", "p50 ms", "vs ECC");
    const auto get = [](const nlohmann::json& row, const char* key) {
      return row[key].is_null() ? std::nan("") : row[key].get<double>();
    };
    for (const nlohmann::json& row : out) {
      std::printf("%-48s %7.1f%% %9.4f %9.4f %9.4f %9.4f %9.2f %9.2f %8.2f%%\n",
                  row["method"].get<std::string>().c_str(), 100.0 * get(row, "failure_rate"),
                  get(row, "rms_px"), get(row, "max_px"), get(row, "rms_deg"),
                  get(row, "max_deg"), get(row, "mean_ms"), get(row, "p50_ms"),
                  100.0 * get(row, "time_vs_ecc"));
    }
  };
}

}  // namespace mosaicloc::app
