#include "mosaicloc/runtime/localization_config.hpp"


#include "mosaicloc/core/error.hpp"
#include "mosaicloc/core/yaml.hpp"

namespace mosaicloc::runtime {

// Keys are read with their types only: every range is the options' Check(), run per section
// so that a complaint names the key and line it is about, then over the whole so that
// nothing goes unchecked.
void ReadLocalizerConfig(const YAML::Node& node, const std::string& file_name, LocalizerConfig* config) {
  core::YamlProblems problems;
  core::YamlMap root = core::YamlMap::Root(node, file_name, &problems);
  localizer::LocalizerOptions& o = config->localizer;
  tracking::TrackerOptions& t = o.tracker;

  core::YamlMap templates = root.OptionalMap("templates");
  templates.OptionalEnum("mode", &t.templates.mode, tracking::kTemplateModes);
  templates.Optional("count", &t.templates.count);
  templates.Optional("size_px", &t.templates.size_px);
  templates.Optional("tile_cols", &t.templates.tile_cols);
  templates.Optional("tile_rows", &t.templates.tile_rows);
  templates.Optional("border_px", &t.templates.border_px);
  templates.Optional("min_texture", &t.templates.min_texture);
  templates.Optional("spares", &t.spare_templates);
  templates.Optional("edge_count", &o.edge_templates);
  templates.Check(t.templates);
  templates.CheckOwnKeys(t, {{"spare_templates", "spares"}});
  templates.CheckOwnKeys(o, {{"edge_templates", "edge_count"}});
  templates.Finish();

  core::YamlMap search = root.OptionalMap("search");
  search.Optional("sigmas", &t.search_sigmas);
  search.Optional("min_range_px", &t.min_search_px);
  search.Optional("max_range_px", &t.max_search_px);
  search.Optional("min_peak", &t.min_peak);
  search.Optional("max_ambiguity", &t.max_ambiguity);
  search.Optional("prefilter_sigma_px", &t.search.prefilter_sigma_px);
  search.Check(t.search);
  search.CheckOwnKeys(t, {{"search_sigmas", "sigmas"}, {"min_search_px", "min_range_px"},
                          {"max_search_px", "max_range_px"}});
  search.Finish();

  core::YamlMap refine = root.OptionalMap("refine");
  refine.OptionalEnum("method", &t.refine.method, tracking::kRefineMethods);
  refine.OptionalEnum("warp", &t.refine.warp, tracking::kRefineWarps);
  refine.Optional("sampling", &t.refine.sampling);
  refine.Optional("max_iterations", &t.refine.max_iterations);
  refine.Optional("prefilter_sigma_px", &t.refine.prefilter_sigma_px);
  refine.Optional("passes", &t.refine_passes);
  refine.Optional("min_zncc", &t.min_zncc);
  refine.Optional("visp_pyramid_levels", &t.refine.visp_pyramid_levels);
  refine.Optional("min_mapped_fraction", &t.refine.min_mapped_fraction);
  refine.Optional("robust", &t.refine.robust);
  refine.Check(t.refine);
  refine.CheckOwnKeys(t, {{"refine_passes", "passes"}});
  refine.Finish();

  core::YamlMap solver = root.OptionalMap("solver");
  solver.OptionalEnum("method", &t.solver.method, tracking::kPoseMethods);
  solver.Optional("observer_prior_sigma_mm", &t.solver.observer_prior_sigma_mm);
  solver.Optional("observer_prior_sigma_deg", &t.solver.observer_prior_sigma_deg);
  solver.Optional("observer_prior_sigma_scale", &t.solver.observer_prior_sigma_scale);
  solver.OptionalEnum("loss", &t.solver.loss, tracking::kRobustLosses);
  solver.Optional("loss_scale_mm", &t.solver.loss_scale_mm);
  solver.Optional("outlier_threshold_mm", &t.solver.outlier_threshold_mm);
  solver.Optional("min_inliers", &t.solver.min_inliers);
  solver.Optional("estimate_scale", &t.solver.estimate_scale);
  solver.Optional("estimate_tilt", &t.solver.estimate_tilt);
  solver.Optional("posterior_variance", &t.solver.posterior_variance);
  solver.Optional("min_tilt_points", &t.solver.min_tilt_points);
  solver.Optional("camera_height_mm", &t.solver.camera_height_mm);
  solver.Optional("tilt_pivot_height_mm", &o.tilt_pivot_height_mm);
  solver.Optional("tilt_sigma_deg", &o.tilt_sigma_deg);
  solver.Optional("tilt_correlation_s", &o.tilt_correlation_s);
  solver.Optional("scale_sigma", &o.scale_sigma);
  solver.Optional("scale_drift_per_sqrt_s", &o.scale_drift_per_sqrt_s);
  solver.Check(t.solver);
  solver.CheckOwnKeys(o);
  solver.Finish();

  core::YamlMap filter = root.OptionalMap("filter");
  filter.Optional("gate_chi2", &o.filter.gate_chi2);
  filter.Optional("fix_sigma_floor_mm", &o.fix_sigma_floor_mm);
  filter.Optional("fix_sigma_floor_rad", &o.fix_sigma_floor_rad);
  filter.Optional("fix_covariance_scale", &o.fix_covariance_scale);
  filter.Optional("max_fixed_sigma_mm", &o.max_fixed_sigma_mm);
  filter.Optional("map_distortion_mm_per_m", &o.map_distortion_mm_per_m);
  filter.Optional("wheel_variance_mm", &o.odometry.wheel_variance_mm);
  filter.Optional("wheel_scale_sigma", &o.filter.wheel_scale_sigma);
  filter.Optional("wheel_scale_walk_per_sqrt_m", &o.filter.wheel_scale_walk_per_sqrt_m);
  filter.Optional("start_sigma_mm", &config->start_sigma_mm);
  filter.Optional("start_sigma_deg", &config->start_sigma_deg);
  filter.Check(o.filter);
  filter.CheckOwnKeys(o.odometry);
  filter.CheckOwnKeys(o);
  filter.CheckOwnKeys(*config);
  filter.Finish();

  core::YamlMap lock = root.OptionalMap("lock");
  lock.Optional("degraded_after_misses", &o.lock.degraded_after_misses);
  lock.Optional("lost_after_misses", &o.lock.lost_after_misses);
  lock.Optional("regain_after_fixes", &o.lock.regain_after_fixes);
  lock.Optional("lost_above_sigma_mm", &o.lock.lost_above_sigma_mm);
  lock.Optional("relocalize_after_misses", &o.relocalize_after_misses);
  lock.Optional("lost_global_every", &o.lost_global_every);
  lock.Optional("off_map_global_every", &o.off_map_global_every);
  lock.Optional("on_map_coverage", &o.on_map_coverage);
  lock.Check(o.lock);
  lock.CheckOwnKeys(o);
  lock.Finish();

  core::YamlMap vo = root.OptionalMap("visual_odometry");
  localizer::VisualOdometryOptions& v = o.visual_odometry;
  vo.Optional("enabled", &v.enabled);
  vo.Optional("keyframe_fraction", &v.keyframe_fraction);
  vo.Optional("max_fraction", &v.max_fraction);
  vo.Optional("keyframe_turn_deg", &v.keyframe_turn_deg);
  vo.Optional("prior_sigma_mm", &v.prior_sigma_mm);
  vo.Optional("prior_sigma_fraction", &v.prior_sigma_fraction);
  vo.Optional("prior_sigma_deg", &v.prior_sigma_deg);
  vo.Optional("link_sigma_floor_mm", &v.link_sigma_floor_mm);
  vo.Optional("link_sigma_floor_rad", &v.link_sigma_floor_rad);
  vo.Optional("roll_deg_per_mps2", &v.roll_deg_per_mps2);
  vo.Optional("turn_sigma_fraction", &v.turn_sigma_fraction);
  vo.Check(v);
  vo.Finish();

  core::YamlMap extension = root.OptionalMap("map_extension");
  extension.Optional("max_segment_m", &config->map_extension.max_segment_m);
  extension.Optional("max_anchor_sigma_mm", &config->map_extension.max_anchor_sigma_mm);
  extension.Optional("return_prior_sigma_mm", &config->map_extension.return_prior_sigma_mm);
  extension.Optional("return_prior_sigma_deg", &config->map_extension.return_prior_sigma_deg);
  extension.Check(config->map_extension);
  extension.Finish();

  core::YamlMap update = root.OptionalMap("map_update");
  mapping::MapUpdateOptions& u = config->map_update;
  update.Optional("enabled", &u.enabled);
  std::int64_t passes = u.passes, min_cells = u.min_cells, min_fixes = u.min_fixes_in_row;
  update.Optional("passes", &passes, core::IntegerInRange(2, 1000));
  update.Optional("min_cells", &min_cells, core::IntegerInRange(1, 100000));
  update.Optional("min_fixes_in_row", &min_fixes, core::IntegerInRange(1, 1000000));
  u.passes = static_cast<int>(passes);
  u.min_cells = static_cast<int>(min_cells);
  u.min_fixes_in_row = static_cast<int>(min_fixes);
  update.Optional("pass_gap_s", &u.pass_gap_s);
  update.Optional("cell_mm", &u.cell_mm);
  update.Optional("min_zncc", &u.min_zncc);
  update.Optional("border_zncc", &u.border_zncc);
  update.Optional("flat_dn", &u.flat_dn);
  update.Optional("max_flat_change_dn", &u.max_flat_change_dn);
  update.Optional("max_changed_share", &u.max_changed_share);
  update.Optional("min_judged_share", &u.min_judged_share);
  update.Optional("max_nis", &u.max_nis);
  update.Optional("max_sigma_mm", &u.max_sigma_mm);
  update.Optional("max_ambiguity", &u.max_ambiguity);
  update.Optional("compare_every_fraction", &u.compare_every_fraction);
  update.Optional("margin_px", &u.margin_px);
  update.Check(u);
  update.Finish();

  core::YamlMap map = root.OptionalMap("map");
  std::int64_t budget = static_cast<std::int64_t>(config->cache_budget_mib);
  map.Optional("cache_budget_mib", &budget, core::IntegerInRange(0, std::int64_t{1} << 40));
  config->cache_budget_mib = static_cast<std::size_t>(budget);
  map.Optional("prefetch_horizon_s", &config->prefetch_horizon_s);
  map.Optional("prefetch_turn_radius_mm", &config->prefetch_turn_radius_mm);
  map.CheckOwnKeys(*config);
  map.Finish();

  root.Optional("required_overlap", &config->required_overlap);
  root.Finish();
  // What no section reported (a rule across sections) is reported for the file.
  if (problems.empty()) root.Check(*config);
  problems.ThrowIfAny();
}

LocalizerConfig LoadLocalizerConfig(const std::filesystem::path& file) {
  LocalizerConfig config;
  ReadLocalizerConfig(core::LoadYamlFile(file), file.string(), &config);
  return config;
}

}  // namespace mosaicloc::runtime
