#include <string>

#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include "mosaicloc/runtime/localization_config.hpp"
#include "mosaicloc/core/error.hpp"

namespace mosaicloc::runtime {
namespace {

// The documented defaults are the compiled ones: a reader can trust the example file.
TEST(LocalizerConfig, DefaultFileEqualsCompiledDefaults) {
  const LocalizerConfig loaded = LoadLocalizerConfig(std::string(MOSAICLOC_CONFIG_DIR) + "/default/localizer.yaml");
  const LocalizerConfig compiled;
  const tracking::TrackerOptions& a = loaded.localizer.tracker;
  const tracking::TrackerOptions& b = compiled.localizer.tracker;
  EXPECT_EQ(a.templates.mode, b.templates.mode);
  EXPECT_EQ(a.templates.count, b.templates.count);
  EXPECT_EQ(a.templates.size_px, b.templates.size_px);
  EXPECT_EQ(a.templates.tile_cols, b.templates.tile_cols);
  EXPECT_EQ(a.templates.tile_rows, b.templates.tile_rows);
  EXPECT_EQ(a.templates.border_px, b.templates.border_px);
  EXPECT_EQ(a.templates.min_texture, b.templates.min_texture);
  EXPECT_EQ(a.spare_templates, b.spare_templates);
  EXPECT_EQ(loaded.localizer.edge_templates, compiled.localizer.edge_templates);
  EXPECT_EQ(loaded.localizer.scale_sigma, compiled.localizer.scale_sigma);
  EXPECT_EQ(loaded.localizer.scale_drift_per_sqrt_s, compiled.localizer.scale_drift_per_sqrt_s);
  EXPECT_EQ(a.search_sigmas, b.search_sigmas);
  EXPECT_EQ(a.min_search_px, b.min_search_px);
  EXPECT_EQ(a.max_search_px, b.max_search_px);
  EXPECT_EQ(a.min_peak, b.min_peak);
  EXPECT_EQ(a.max_ambiguity, b.max_ambiguity);
  EXPECT_EQ(a.search.prefilter_sigma_px, b.search.prefilter_sigma_px);
  EXPECT_EQ(a.refine.method, b.refine.method);
  EXPECT_EQ(a.refine.warp, b.refine.warp);
  EXPECT_EQ(a.refine.sampling, b.refine.sampling);
  EXPECT_EQ(a.refine.max_iterations, b.refine.max_iterations);
  EXPECT_EQ(a.refine.prefilter_sigma_px, b.refine.prefilter_sigma_px);
  EXPECT_EQ(a.refine_passes, b.refine_passes);
  EXPECT_EQ(a.min_zncc, b.min_zncc);
  EXPECT_EQ(a.refine.visp_pyramid_levels, b.refine.visp_pyramid_levels);
  EXPECT_EQ(a.refine.min_mapped_fraction, b.refine.min_mapped_fraction);
  EXPECT_EQ(a.refine.robust, b.refine.robust);
  EXPECT_EQ(a.solver.loss, b.solver.loss);
  EXPECT_EQ(a.solver.loss_scale_mm, b.solver.loss_scale_mm);
  EXPECT_EQ(a.solver.outlier_threshold_mm, b.solver.outlier_threshold_mm);
  EXPECT_EQ(a.solver.min_inliers, b.solver.min_inliers);
  EXPECT_EQ(a.solver.estimate_scale, b.solver.estimate_scale);
  EXPECT_EQ(a.solver.posterior_variance, b.solver.posterior_variance);
  EXPECT_EQ(a.solver.estimate_tilt, b.solver.estimate_tilt);
  EXPECT_EQ(a.solver.min_tilt_points, b.solver.min_tilt_points);
  const localizer::LocalizerOptions& l = loaded.localizer;
  const localizer::LocalizerOptions& m = compiled.localizer;
  EXPECT_EQ(l.filter.gate_chi2, m.filter.gate_chi2);
  EXPECT_EQ(l.fix_sigma_floor_mm, m.fix_sigma_floor_mm);
  EXPECT_EQ(l.fix_sigma_floor_rad, m.fix_sigma_floor_rad);
  EXPECT_EQ(l.fix_covariance_scale, m.fix_covariance_scale);
  EXPECT_EQ(l.max_fixed_sigma_mm, m.max_fixed_sigma_mm);
  EXPECT_EQ(l.tilt_pivot_height_mm, m.tilt_pivot_height_mm);
  EXPECT_EQ(l.tilt_sigma_deg, m.tilt_sigma_deg);
  EXPECT_EQ(l.tilt_correlation_s, m.tilt_correlation_s);
  EXPECT_EQ(l.map_distortion_mm_per_m, m.map_distortion_mm_per_m);
  EXPECT_EQ(l.odometry.wheel_variance_mm, m.odometry.wheel_variance_mm);
  EXPECT_EQ(l.lock.degraded_after_misses, m.lock.degraded_after_misses);
  EXPECT_EQ(l.lock.lost_after_misses, m.lock.lost_after_misses);
  EXPECT_EQ(l.lock.regain_after_fixes, m.lock.regain_after_fixes);
  EXPECT_EQ(l.lock.lost_above_sigma_mm, m.lock.lost_above_sigma_mm);
  EXPECT_EQ(l.relocalize_after_misses, m.relocalize_after_misses);
  EXPECT_EQ(l.on_map_coverage, m.on_map_coverage);
  EXPECT_EQ(l.filter.wheel_scale_sigma, m.filter.wheel_scale_sigma);
  EXPECT_EQ(l.filter.wheel_scale_walk_per_sqrt_m, m.filter.wheel_scale_walk_per_sqrt_m);
  EXPECT_EQ(loaded.start_sigma_mm, compiled.start_sigma_mm);
  EXPECT_EQ(loaded.start_sigma_deg, compiled.start_sigma_deg);
  EXPECT_EQ(loaded.cache_budget_mib, compiled.cache_budget_mib);
  EXPECT_EQ(loaded.prefetch_horizon_s, compiled.prefetch_horizon_s);
  EXPECT_EQ(loaded.prefetch_turn_radius_mm, compiled.prefetch_turn_radius_mm);
  EXPECT_EQ(loaded.required_overlap, compiled.required_overlap);
}

TEST(LocalizerConfig, EveryProblemIsReportedWithFileLineAndKey) {
  const YAML::Node node = YAML::Load("templates:\n  count: 0\nrefine:\n  metod: direct\nlock:\n  lost_after_misses: 1\n");
  LocalizerConfig config;
  try {
    ReadLocalizerConfig(node, "site.yaml", &config);
    FAIL() << "expected an error";
  } catch (const core::Error& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("site.yaml:2"), std::string::npos) << message;
    EXPECT_NE(message.find("templates.count"), std::string::npos) << message;
    EXPECT_NE(message.find("did you mean 'method'"), std::string::npos) << message;
    EXPECT_NE(message.find("lock.lost_after_misses: must be >= degraded_after_misses"), std::string::npos) << message;
  }
}

// Off the map must mean less mapped than a relocalized place may be: a lower share is refused
// with the file, line and key.
TEST(LocalizerConfig, OnMapCoverageBelowTheRelocalizationShareIsRefused) {
  LocalizerConfig config;
  try {
    ReadLocalizerConfig(YAML::Load("lock:\n  on_map_coverage: 0.5\n"), "site.yaml", &config);
    FAIL() << "expected an error";
  } catch (const core::Error& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("site.yaml:2"), std::string::npos) << message;
    EXPECT_NE(message.find("on_map_coverage"), std::string::npos) << message;
  }
  ReadLocalizerConfig(YAML::Load("lock:\n  on_map_coverage: 0.9\n"), "site.yaml", &config);
  EXPECT_EQ(config.localizer.on_map_coverage, 0.9);
}

}  // namespace
}  // namespace mosaicloc::runtime
