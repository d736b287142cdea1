#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "mosaicloc/core/pose2.hpp"

namespace mosaicloc::mapping {

/// What an edge of the pose graph measured.
enum class EdgeKind {
  kSequential,  ///< a frame registered against the one before it (or the wheels' motion where it was not)
  kLoop,        ///< a frame registered against an earlier one that sees the same floor
};
const char* ToString(EdgeKind kind);

/// A relative pose measurement between two nodes: `from_T_to` is from_from_to (the pose of
/// node `to` in node `from`'s frame), `information` the inverse of its covariance
/// (x_mm, y_mm, yaw_rad), symmetric positive definite.
struct PoseGraphEdge {
  int from = 0;
  int to = 0;
  core::Pose2 from_T_to;
  Eigen::Matrix3d information = Eigen::Matrix3d::Identity();
  EdgeKind kind = EdgeKind::kSequential;
};

/// A 2-D pose graph: nodes are world_from_node poses (mm, rad), edges relative measurements.
struct PoseGraph {
  std::vector<core::Pose2> nodes;
  std::vector<PoseGraphEdge> edges;
  /// Nodes held where they are (the gauge); when empty, the first node of every connected
  /// piece is held.
  std::vector<int> fixed;
};

/// Whitened residual r of an edge at the graph's poses: r = L e with Lᵀ L the information and
/// e = (R_fromᵀ (p_to - p_from) - measured translation, predicted yaw - measured yaw), the
/// error of Ceres' pose_graph_2d; |r|² is the edge's chi-square (3 degrees of freedom).
Eigen::Vector3d EdgeResidual(const PoseGraph& graph, const PoseGraphEdge& edge);

struct OptimizeOptions {
  /// Loop edges are weighted by a Huber loss of this many (whitened) standard deviations, so
  /// a wrong loop closure pulls with a bounded force instead of bending the map. 0: no robust
  /// loss, for a loop that is the only hold a chain has at its end (a bounded force there
  /// leaves the chain's drift standing where it meets the map).
  double loop_huber_sigmas = 3.0;
  int max_iterations = 200;
  int threads = 1;
  /// Start the solve from the linear estimate (yaws, then positions, each a sparse linear
  /// least-squares problem) instead of the nodes' poses: far from the optimum (a long chain's
  /// drift) the nonlinear solve then needs a few iterations instead of tens.
  bool linear_initialization = true;
};

struct OptimizeReport {
  bool converged = false;
  int iterations = 0;
  double initial_cost = 0.0;
  double final_cost = 0.0;
  double seconds = 0.0;
  int pieces = 0;  ///< connected pieces of the graph (each has its own gauge)
  bool initialized = false;             ///< started from the linear estimate
  double initialization_seconds = 0.0;
  std::string message;
};

/// Solves the graph in place with Ceres (the formulation of Ceres' pose_graph_2d example:
/// a position and a yaw block per node, the yaw on a wrapped-angle manifold), the fixed
/// nodes held. Throws core::Error (invalid input) for an edge naming a missing node or an
/// information matrix that is not symmetric positive definite.
OptimizeReport Optimize(PoseGraph& graph, const OptimizeOptions& options = {});

/// The graph in g2o's text format, as other 2-D mapping tools read it: `VERTEX_SE2 id x y
/// theta` (metres, radians), `EDGE_SE2 from to dx dy dtheta` and the upper triangle of the
/// information matrix (in metres, of g2o's error: the translation turned by the measured yaw),
/// `FIX id` for held nodes; a comment line `# loop` before each loop closure's edge. Written
/// atomically.
void WriteG2o(const std::filesystem::path& file, const PoseGraph& graph);

/// Reads a g2o file written by WriteG2o or another tool (VERTEX_SE2, EDGE_SE2, FIX; comment
/// lines start with '#'). Node ids must be 0..n-1 in any order. In a file WriteG2o wrote, the
/// loops are the marked edges; in another tool's, every edge that does not join consecutive
/// nodes. Throws core::Error (invalid
/// input) naming the file and line of the first problem.
PoseGraph ReadG2o(const std::filesystem::path& file);

}  // namespace mosaicloc::mapping
