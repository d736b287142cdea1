#include "localizer_config.hpp"

#include <cmath>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/core/yaml.hpp"

namespace mosaicloc::app {

void ReadLocalizerConfig(const YAML::Node& node, const std::string& file_name, LocalizerConfig* config) {
  using core::InRange;
  using core::IntegerInRange;
  using core::Positive;
  core::YamlProblems problems;
  core::YamlMap root = core::YamlMap::Root(node, file_name, &problems);
  localizer::LocalizerOptions& o = config->localizer;

  core::YamlMap templates = root.OptionalMap("templates");
  std::string mode = o.tracker.templates.mode == tracking::TemplateMode::kTiled ? "tiled" : "spread";
  templates.Optional("mode", &mode, core::OneOf({"spread", "tiled"}));
  o.tracker.templates.mode = mode == "tiled" ? tracking::TemplateMode::kTiled : tracking::TemplateMode::kSpread;
  templates.Optional("count", &o.tracker.templates.count, IntegerInRange(1, 64));
  templates.Optional("size_px", &o.tracker.templates.size_px, IntegerInRange(16, 1024));
  templates.Optional("tile_cols", &o.tracker.templates.tile_cols, IntegerInRange(1, 16));
  templates.Optional("tile_rows", &o.tracker.templates.tile_rows, IntegerInRange(1, 16));
  templates.Optional("border_px", &o.tracker.templates.border_px, IntegerInRange(1, 256));
  templates.Optional("min_texture", &o.tracker.templates.min_texture, InRange(0.0, 1e6));
  templates.Optional("spares", &o.tracker.spare_templates, IntegerInRange(0, 64));
  templates.Optional("edge_count", &o.edge_templates, IntegerInRange(0, 64));
  templates.Finish();

  core::YamlMap search = root.OptionalMap("search");
  search.Optional("sigmas", &o.tracker.search_sigmas, InRange(0.5, 20.0));
  search.Optional("min_range_px", &o.tracker.min_search_px, IntegerInRange(1, 1024));
  search.Optional("max_range_px", &o.tracker.max_search_px, IntegerInRange(1, 4096));
  search.Optional("min_peak", &o.tracker.min_peak, InRange(-0.99, 0.99));
  search.Optional("max_ambiguity", &o.tracker.max_ambiguity, InRange(0.01, 1.0));
  search.Optional("prefilter_sigma_px", &o.tracker.search.prefilter_sigma_px, InRange(0.0, 5.0));
  search.Finish();
  if (o.tracker.max_search_px < o.tracker.min_search_px) {
    root.AddProblem("search", "max_range_px must be at least min_range_px");
  }

  core::YamlMap refine = root.OptionalMap("refine");
  std::string method = o.tracker.refine.method == tracking::RefineMethod::kDirect     ? "direct"
                       : o.tracker.refine.method == tracking::RefineMethod::kVispSsd ? "visp-ssd"
                                                                                      : "visp-zncc";
  refine.Optional("method", &method, core::OneOf({"direct", "visp-ssd", "visp-zncc"}));
  o.tracker.refine.method = method == "direct"     ? tracking::RefineMethod::kDirect
                            : method == "visp-ssd" ? tracking::RefineMethod::kVispSsd
                                                   : tracking::RefineMethod::kVispZncc;
  std::string warp = o.tracker.refine.warp == tracking::RefineWarp::kTranslation ? "translation"
                     : o.tracker.refine.warp == tracking::RefineWarp::kSrt       ? "srt"
                                                                                 : "homography";
  refine.Optional("warp", &warp, core::OneOf({"translation", "srt", "homography"}));
  o.tracker.refine.warp = warp == "translation" ? tracking::RefineWarp::kTranslation
                          : warp == "srt"       ? tracking::RefineWarp::kSrt
                                                : tracking::RefineWarp::kHomography;
  if (method == "direct" && warp != "translation") {
    refine.AddProblem("warp", "the direct method estimates a translation only; use warp: translation");
  }
  refine.Optional("sampling", &o.tracker.refine.sampling, IntegerInRange(1, 8));
  refine.Optional("max_iterations", &o.tracker.refine.max_iterations, IntegerInRange(1, 1000));
  refine.Optional("prefilter_sigma_px", &o.tracker.refine.prefilter_sigma_px, InRange(0.0, 5.0));
  refine.Optional("passes", &o.tracker.refine_passes, IntegerInRange(0, 5));
  refine.Optional("min_zncc", &o.tracker.min_zncc, InRange(-0.99, 0.99));
  refine.Optional("visp_pyramid_levels", &o.tracker.refine.visp_pyramid_levels, IntegerInRange(1, 4));
  refine.Optional("min_mapped_fraction", &o.tracker.refine.min_mapped_fraction, InRange(0.01, 1.0));
  refine.Finish();

  core::YamlMap solver = root.OptionalMap("solver");
  std::string loss = o.tracker.solver.loss == tracking::RobustLoss::kCauchy  ? "cauchy"
                     : o.tracker.solver.loss == tracking::RobustLoss::kHuber ? "huber"
                                                                             : "none";
  solver.Optional("loss", &loss, core::OneOf({"cauchy", "huber", "none"}));
  o.tracker.solver.loss = loss == "cauchy"  ? tracking::RobustLoss::kCauchy
                          : loss == "huber" ? tracking::RobustLoss::kHuber
                                            : tracking::RobustLoss::kNone;
  solver.Optional("loss_scale_mm", &o.tracker.solver.loss_scale_mm, Positive());
  solver.Optional("outlier_threshold_mm", &o.tracker.solver.outlier_threshold_mm, Positive());
  solver.Optional("min_inliers", &o.tracker.solver.min_inliers, IntegerInRange(1, 64));
  solver.Finish();

  core::YamlMap filter = root.OptionalMap("filter");
  filter.Optional("gate_chi2", &o.filter.gate_chi2, Positive());
  filter.Optional("fix_sigma_floor_mm", &o.fix_sigma_floor_mm, InRange(0.0, 100.0));
  filter.Optional("fix_sigma_floor_rad", &o.fix_sigma_floor_rad, InRange(0.0, 1.0));
  filter.Optional("fix_covariance_scale", &o.fix_covariance_scale, InRange(1.0, 1e6));
  filter.Optional("wheel_variance_mm", &o.odometry.wheel_variance_mm, InRange(0.0, 100.0));
  filter.Optional("wheel_scale_sigma", &o.filter.wheel_scale_sigma, InRange(0.0, 0.5));
  filter.Optional("wheel_scale_walk_per_sqrt_m", &o.filter.wheel_scale_walk_per_sqrt_m, InRange(0.0, 0.1));
  filter.Optional("start_sigma_mm", &config->start_sigma_mm, InRange(1e-3, 1e5));
  filter.Optional("start_sigma_deg", &config->start_sigma_deg, InRange(1e-4, 180.0));
  filter.Finish();

  core::YamlMap lock = root.OptionalMap("lock");
  lock.Optional("degraded_after_misses", &o.lock.degraded_after_misses, IntegerInRange(1, 100000));
  lock.Optional("lost_after_misses", &o.lock.lost_after_misses, IntegerInRange(1, 100000));
  lock.Optional("regain_after_fixes", &o.lock.regain_after_fixes, IntegerInRange(1, 100000));
  lock.Optional("lost_above_sigma_mm", &o.lock.lost_above_sigma_mm, Positive());
  lock.Optional("relocalize_after_misses", &o.relocalize_after_misses, IntegerInRange(0, 100000));
  lock.Optional("on_map_coverage", &o.on_map_coverage, InRange(o.relocalize.min_coverage, 1.0));
  lock.Finish();
  if (o.lock.lost_after_misses < o.lock.degraded_after_misses) {
    root.AddProblem("lock", "lost_after_misses must be at least degraded_after_misses");
  }

  core::YamlMap map = root.OptionalMap("map");
  std::int64_t budget = static_cast<std::int64_t>(config->cache_budget_mib);
  map.Optional("cache_budget_mib", &budget, IntegerInRange(16, 1 << 20));
  config->cache_budget_mib = static_cast<std::size_t>(budget);
  map.Optional("prefetch_horizon_s", &config->prefetch_horizon_s, InRange(0.0, 10.0));
  map.Optional("prefetch_turn_radius_mm", &config->prefetch_turn_radius_mm, InRange(0.0, 1e6));
  map.Finish();

  root.Optional("required_overlap", &config->required_overlap, InRange(0.0, 0.95));
  root.Finish();
  problems.ThrowIfAny();
}

LocalizerConfig LoadLocalizerConfig(const std::filesystem::path& file) {
  LocalizerConfig config;
  ReadLocalizerConfig(core::LoadYamlFile(file), file.string(), &config);
  return config;
}

}  // namespace mosaicloc::app
