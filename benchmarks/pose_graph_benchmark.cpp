// The pose graph of a long mapping drive: a serpentine survey of N frames (8 mm apart, rows of
// 4 m, 120 mm between rows, so that each row overlaps the one before), sequential and keyframe
// edges with the registration's noise (0.01 mm, 0.001 degrees) and a yaw bias (the chain's
// drift), a loop edge wherever
// a frame's view overlaps the row before, one every 30 mm. Solves it and reports the time,
// Ceres' iterations, the peak resident memory and the error against the truth.
//
//   mosaicloc_pose_graph_benchmark --frames 100000 [--threads 1]
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <numbers>
#include <random>
#include <string>

#include <CLI/CLI.hpp>

#include "resident_memory.hpp"

#include "mosaicloc/mapping/pose_graph.hpp"

namespace {

using namespace mosaicloc;

using bench::PeakResidentMib;

Eigen::Matrix3d Information(double sigma_mm, double sigma_rad) {
  return Eigen::Vector3d(1.0 / (sigma_mm * sigma_mm), 1.0 / (sigma_mm * sigma_mm), 1.0 / (sigma_rad * sigma_rad))
      .asDiagonal();
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app("Solves the pose graph of a long simulated survey drive");
  int frames = 100000;
  int threads = 1;
  bool no_initialization = false;
  app.add_flag("--no-linear-initialization", no_initialization, "Start from the chained poses");
  double yaw_bias_deg_per_m = 0.02;
  app.add_option("--yaw-bias-deg-per-m", yaw_bias_deg_per_m,
                 "The chain's systematic yaw drift (default 0.02, the mapper's drift_deg_per_m)");
  app.add_option("--frames", frames, "Nodes (frames) of the graph")->check(CLI::Range(100, 10000000));
  app.add_option("--threads", threads, "Ceres threads")->check(CLI::Range(1, 64));
  CLI11_PARSE(app, argc, argv);

  const double step_mm = 8.0, row_mm = 4000.0, spacing_mm = 120.0;
  const int per_row = static_cast<int>(row_mm / step_mm);
  std::vector<core::Pose2> truth;
  for (int i = 0; i < frames; ++i) {
    const int row = i / per_row, k = i % per_row;
    const bool forward = row % 2 == 0;
    const double x = forward ? k * step_mm : row_mm - k * step_mm;
    truth.emplace_back(x, row * spacing_mm, forward ? 0.0 : std::numbers::pi);
  }
  const double bias_rad = yaw_bias_deg_per_m * std::numbers::pi / 180.0 * step_mm * 1e-3;
  std::mt19937 rng(7);
  std::normal_distribution<double> mm(0.0, 0.01), rad(0.0, 2e-5);
  mapping::PoseGraph graph;
  graph.nodes.push_back(truth[0]);
  auto measured = [&](int a, int b) {
    const core::Pose2 exact = core::Between(truth[a], truth[b]);
    return core::Pose2(exact.x_mm() + mm(rng), exact.y_mm() + mm(rng), exact.yaw_rad() + rad(rng) + bias_rad);
  };
  const Eigen::Matrix3d registration = Information(0.01, 2e-5);
  for (int i = 1; i < frames; ++i) {
    const core::Pose2 m = measured(i - 1, i);
    graph.edges.push_back({i - 1, i, m, registration, mapping::EdgeKind::kSequential});
    graph.nodes.push_back(graph.nodes.back() * m);
    if (i >= 10) graph.edges.push_back({i - 10, i, measured(i - 10, i), registration, mapping::EdgeKind::kSequential});
  }
  std::int64_t loops = 0;
  for (int i = per_row; i < frames; i += 4) {  // every 32 mm: the frame across in the row before
    const int row = i / per_row, k = i % per_row;
    const int across = (row - 1) * per_row + (per_row - 1 - k);
    graph.edges.push_back({across, i, measured(across, i), registration, mapping::EdgeKind::kLoop});
    ++loops;
  }
  double chained_max = 0.0;
  for (int i = 0; i < frames; ++i) chained_max = std::max(chained_max, core::Distance(graph.nodes[i], truth[i]));
  const double before_mib = PeakResidentMib();
  mapping::OptimizeOptions options;
  options.threads = threads;
  options.linear_initialization = !no_initialization;
  const auto started = std::chrono::steady_clock::now();
  const mapping::OptimizeReport report = mapping::Optimize(graph, options);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  double max_mm = 0.0, sum = 0.0;
  for (int i = 0; i < frames; ++i) {
    const double e = core::Distance(graph.nodes[i], truth[i]);
    max_mm = std::max(max_mm, e);
    sum += e * e;
  }
  std::printf("%d nodes, %zu edges (%lld loops), %.1f km: solved in %.2f s (%d iterations, %s), "
              "peak resident %.0f MiB (%.0f MiB before solving)\n",
              frames, graph.edges.size(), static_cast<long long>(loops), frames * step_mm * 1e-6, seconds,
              report.iterations, report.converged ? "converged" : report.message.c_str(), PeakResidentMib(),
              before_mib);
  std::printf("linear initialization: %s, %.2f s; cost %.4g to %.4g\n", report.initialized ? "yes" : "no",
              report.initialization_seconds, report.initial_cost, report.final_cost);
  std::printf("error against the truth: chained %.2f mm max; optimized %.4f mm RMS, %.4f mm max\n", chained_max,
              std::sqrt(sum / frames), max_mm);
  return report.converged ? 0 : 1;
}
