#include "mosaicloc/mapping/pose_graph.hpp"

#include <cmath>
#include <fstream>
#include <numbers>
#include <random>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/test/test_support.hpp"

namespace mosaicloc::mapping {
namespace {

// Nodes on a circle of radius 2 m, heading along it: a drive that comes back to its start.
std::vector<core::Pose2> Circle(int n) {
  std::vector<core::Pose2> poses;
  for (int i = 0; i < n; ++i) {
    const double a = 2.0 * std::numbers::pi * i / n;
    poses.emplace_back(2000.0 * std::cos(a), 2000.0 * std::sin(a), a + std::numbers::pi / 2.0);
  }
  return poses;
}

Eigen::Matrix3d Information(double sigma_mm, double sigma_rad) {
  return Eigen::Vector3d(1.0 / (sigma_mm * sigma_mm), 1.0 / (sigma_mm * sigma_mm), 1.0 / (sigma_rad * sigma_rad))
      .asDiagonal();
}

// The circle as a drive measures it: consecutive edges with a bias in yaw and noise (the
// chain's drift), and one loop edge, exact, from the last node back to the first. The nodes
// start at the chained poses.
PoseGraph DriftedCircle(const std::vector<core::Pose2>& truth, double yaw_bias_rad, double sigma_mm = 0.1,
                        double sigma_rad = 1e-3) {
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, sigma_mm);
  PoseGraph graph;
  graph.nodes.push_back(truth[0]);
  for (std::size_t i = 1; i < truth.size(); ++i) {
    const core::Pose2 exact = core::Between(truth[i - 1], truth[i]);
    const core::Pose2 measured(exact.x_mm() + noise(rng), exact.y_mm() + noise(rng), exact.yaw_rad() + yaw_bias_rad);
    graph.edges.push_back({static_cast<int>(i - 1), static_cast<int>(i), measured, Information(sigma_mm, sigma_rad),
                           EdgeKind::kSequential});
    graph.nodes.push_back(graph.nodes.back() * measured);
  }
  const int last = static_cast<int>(truth.size()) - 1;
  graph.edges.push_back({last, 0, core::Between(truth[last], truth[0]), Information(0.05, 1e-4), EdgeKind::kLoop});
  return graph;
}

double MaxError(const std::vector<core::Pose2>& a, const std::vector<core::Pose2>& b) {
  double worst = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i) worst = std::max(worst, core::Distance(a[i], b[i]));
  return worst;
}

TEST(PoseGraph, ALoopClosureTakesOutTheChainsDrift) {
  const std::vector<core::Pose2> truth = Circle(60);
  PoseGraph graph = DriftedCircle(truth, 1e-3);
  const double before = MaxError(graph.nodes, truth);
  ASSERT_GT(before, 50.0) << "the chain drifted";
  const OptimizeReport report = Optimize(graph);
  EXPECT_TRUE(report.converged) << report.message;
  EXPECT_EQ(report.pieces, 1);
  EXPECT_LT(report.final_cost, report.initial_cost);
  EXPECT_LT(MaxError(graph.nodes, truth), 3.0);
  EXPECT_EQ(core::Distance(graph.nodes[0], truth[0]), 0.0) << "the first node is the gauge";
  // Every edge agrees with the solution within a few of its standard deviations.
  for (const PoseGraphEdge& e : graph.edges) EXPECT_LT(EdgeResidual(graph, e).norm(), 6.0) << e.from << "-" << e.to;
}

// Far from the optimum (a chain that drifted a tenth of a turn), the linear start reaches the same
// solution in fewer iterations.
TEST(PoseGraph, TheLinearStartNeedsFewerIterations) {
  const std::vector<core::Pose2> truth = Circle(200);
  PoseGraph linear = DriftedCircle(truth, 3e-3, 0.01, 2e-5);
  linear.edges.back().kind = EdgeKind::kSequential;  // trusted: a robust loss would give up on it
  PoseGraph chained = linear;
  OptimizeOptions options;
  const OptimizeReport a = Optimize(linear, options);
  options.linear_initialization = false;
  const OptimizeReport b = Optimize(chained, options);
  EXPECT_TRUE(a.converged && a.initialized) << a.message;
  EXPECT_TRUE(b.converged && !b.initialized) << b.message;
  EXPECT_LT(a.iterations, b.iterations);
  EXPECT_NEAR(a.final_cost, b.final_cost, 1e-6 * b.final_cost + 1e-9);
  EXPECT_LT(MaxError(linear.nodes, chained.nodes), 0.05) << "the same optimum, to the solver's tolerance";
}

TEST(PoseGraph, AWrongLoopPullsWithABoundedForce) {
  const std::vector<core::Pose2> truth = Circle(60);
  // A chain as stiff as registered frames make it (0.01 mm, 0.001 degrees an edge) without
  // drift, and a confident loop that puts node 30 a pattern period (100 mm) away from where
  // node 0 saw it.
  PoseGraph graph = DriftedCircle(truth, 0.0, 0.01, 2e-5);
  const core::Pose2 wrong = core::Between(truth[0], truth[30]) * core::Pose2(100.0, 0.0, 0.0);
  graph.edges.push_back({0, 30, wrong, Information(0.05, 1e-4), EdgeKind::kLoop});
  PoseGraph trusting = graph;
  trusting.edges.back().kind = EdgeKind::kSequential;  // the same edge without the robust loss
  Optimize(graph);
  Optimize(trusting);
  const double robust = MaxError(graph.nodes, truth), bent = MaxError(trusting.nodes, truth);
  EXPECT_GT(bent, 30.0) << "trusted, the wrong loop bends the map";
  EXPECT_LT(robust, bent / 4.0);
  EXPECT_GT(EdgeResidual(graph, graph.edges.back()).squaredNorm(), 16.27) << "and it stands out by its residual";
}

TEST(PoseGraph, UnconnectedPiecesKeepTheirOwnGauge) {
  PoseGraph graph;
  graph.nodes = {core::Pose2(0, 0, 0), core::Pose2(90, 5, 0.01), core::Pose2(500, 500, 1.0), core::Pose2(600, 480, 1.1)};
  graph.edges.push_back({0, 1, core::Pose2(100, 0, 0), Information(1, 0.01), EdgeKind::kSequential});
  graph.edges.push_back({2, 3, core::Pose2(100, 0, 0), Information(1, 0.01), EdgeKind::kSequential});
  const OptimizeReport report = Optimize(graph);
  EXPECT_EQ(report.pieces, 2);
  EXPECT_EQ(core::Distance(graph.nodes[0], core::Pose2(0, 0, 0)), 0.0);
  EXPECT_EQ(core::Distance(graph.nodes[2], core::Pose2(500, 500, 1.0)), 0.0);
  EXPECT_LT(core::Distance(graph.nodes[1], core::Pose2(100, 0, 0)), 1e-6);
  EXPECT_LT(core::Distance(graph.nodes[3], core::Pose2(500, 500, 1.0) * core::Pose2(100, 0, 0)), 1e-6);
}

TEST(PoseGraph, AFixedNodeHoldsItsPieceInPlaceOfTheFirst) {
  PoseGraph graph;
  graph.nodes = {core::Pose2(0, 0, 0), core::Pose2(100, 0, 0)};
  graph.edges.push_back({0, 1, core::Pose2(50, 0, 0), Information(1, 0.01), EdgeKind::kSequential});
  graph.fixed = {1};
  Optimize(graph);
  EXPECT_EQ(core::Distance(graph.nodes[1], core::Pose2(100, 0, 0)), 0.0);
  EXPECT_LT(core::Distance(graph.nodes[0], core::Pose2(50, 0, 0)), 1e-6);
}

TEST(PoseGraph, InvalidEdgesAreRejected) {
  PoseGraph graph;
  graph.nodes = {core::Pose2(), core::Pose2()};
  graph.edges.push_back({0, 2, core::Pose2(), Information(1, 0.01), EdgeKind::kSequential});
  EXPECT_THROW(Optimize(graph), core::Error);
  graph.edges.back().to = 1;
  graph.edges.back().information(0, 0) = -1.0;
  EXPECT_THROW(Optimize(graph), core::Error);
  graph.edges.back().information = Information(1, 0.01);
  graph.edges.back().information(0, 1) = 0.5;  // not symmetric
  EXPECT_THROW(Optimize(graph), core::Error);
}

TEST(PoseGraph, G2oRoundTripKeepsEveryNumber) {
  test::ScratchDir scratch;
  PoseGraph graph = DriftedCircle(Circle(12), 1e-3);
  Eigen::Matrix3d correlated;
  correlated << 4.0, 0.5, 0.1, 0.5, 3.0, -0.2, 0.1, -0.2, 2e4;
  graph.edges.push_back({2, 9, core::Pose2(1.5, -2.25, 0.125), correlated, EdgeKind::kLoop});
  graph.edges.push_back({3, 7, core::Pose2(0.5, 0.25, -0.5), correlated, EdgeKind::kSequential});  // a keyframe's
  graph.fixed = {0, 5};
  const auto file = scratch.path() / "graph.g2o";
  WriteG2o(file, graph);
  const PoseGraph read = ReadG2o(file);
  ASSERT_EQ(read.nodes.size(), graph.nodes.size());
  ASSERT_EQ(read.edges.size(), graph.edges.size());
  EXPECT_EQ(read.fixed, graph.fixed);
  for (std::size_t i = 0; i < graph.nodes.size(); ++i) {
    EXPECT_NEAR(read.nodes[i].x_mm(), graph.nodes[i].x_mm(), 1e-9);
    EXPECT_NEAR(read.nodes[i].y_mm(), graph.nodes[i].y_mm(), 1e-9);
    EXPECT_NEAR(read.nodes[i].yaw_rad(), graph.nodes[i].yaw_rad(), 1e-12);
  }
  for (std::size_t i = 0; i < graph.edges.size(); ++i) {
    const PoseGraphEdge &a = graph.edges[i], &b = read.edges[i];
    EXPECT_EQ(a.from, b.from);
    EXPECT_EQ(a.to, b.to);
    EXPECT_EQ(a.kind, b.kind);
    EXPECT_NEAR(a.from_T_to.x_mm(), b.from_T_to.x_mm(), 1e-9);
    EXPECT_NEAR(a.from_T_to.y_mm(), b.from_T_to.y_mm(), 1e-9);
    EXPECT_NEAR(a.from_T_to.yaw_rad(), b.from_T_to.yaw_rad(), 1e-12);
    EXPECT_LT((a.information - b.information).cwiseAbs().maxCoeff(), 1e-9 * a.information.cwiseAbs().maxCoeff());
  }
  // The graph read back solves to the same poses.
  PoseGraph solved = graph, solved_read = read;
  Optimize(solved);
  Optimize(solved_read);
  EXPECT_LT(MaxError(solved.nodes, solved_read.nodes), 1e-6);
}

// The information written is that of g2o's own error, toVector(measured⁻¹ (from⁻¹ to)) in
// metres: at any poses, its chi-square is the edge's here.
TEST(PoseGraph, G2oInformationIsInG2osErrorFrame) {
  test::ScratchDir scratch;
  PoseGraph graph;
  graph.nodes = {core::Pose2(10.0, -20.0, 0.3), core::Pose2(140.0, 35.0, 1.2)};
  Eigen::Matrix3d information;
  information << 9.0, 2.0, 0.5, 2.0, 1.0, -0.3, 0.5, -0.3, 4e4;
  graph.edges.push_back({0, 1, core::Pose2(120.0, 95.0, 0.8), information, EdgeKind::kLoop});
  const auto file = scratch.path() / "one.g2o";
  WriteG2o(file, graph);
  std::ifstream in(file);
  std::string line;
  std::vector<double> v;
  while (std::getline(in, line)) {
    if (line.rfind("EDGE_SE2", 0) != 0) continue;
    std::istringstream fields(line.substr(8));
    for (double x; fields >> x;) v.push_back(x);
  }
  ASSERT_EQ(v.size(), 11U);
  Eigen::Matrix3d omega;
  omega << v[5], v[6], v[7], v[6], v[8], v[9], v[7], v[9], v[10];
  const core::Pose2 measured(v[2], v[3], v[4]);  // metres
  auto metres = [](const core::Pose2& p) { return core::Pose2(p.x_mm() * 1e-3, p.y_mm() * 1e-3, p.yaw_rad()); };
  const core::Pose2 error = measured.Inverse() * (metres(graph.nodes[0]).Inverse() * metres(graph.nodes[1]));
  const Eigen::Vector3d e(error.x_mm(), error.y_mm(), error.yaw_rad());
  EXPECT_NEAR(e.dot(omega * e), EdgeResidual(graph, graph.edges[0]).squaredNorm(), 1e-9 * e.dot(omega * e));
  EXPECT_GT(e.dot(omega * e), 1.0) << "the poses are off the measurement";
}

TEST(PoseGraph, AnotherToolsG2oFileHasItsLoopsFoundByTheirNodes) {
  test::ScratchDir scratch;
  const auto file = scratch.path() / "foreign.g2o";
  std::ofstream(file) << "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 0.1 0 0\nVERTEX_SE2 2 0.2 0 0\n"
                      << "EDGE_SE2 0 1 0.1 0 0 1e6 0 0 1e6 0 1e4\nEDGE_SE2 1 2 0.1 0 0 1e6 0 0 1e6 0 1e4\n"
                      << "EDGE_SE2 0 2 0.2 0 0 1e6 0 0 1e6 0 1e4\n";
  const PoseGraph graph = ReadG2o(file);
  ASSERT_EQ(graph.edges.size(), 3U);
  EXPECT_EQ(graph.edges[1].kind, EdgeKind::kSequential);
  EXPECT_EQ(graph.edges[2].kind, EdgeKind::kLoop);
}

// A g2o file with one line replaced by `bad` is rejected naming the file and that line.
void ExpectRejectedAtLine(const std::string& bad, int line, const std::string& reason) {
  test::ScratchDir scratch;
  const auto file = scratch.path() / "bad.g2o";
  std::ofstream(file) << "# a graph\n"
                      << "VERTEX_SE2 0 0 0 0\n"
                      << "VERTEX_SE2 1 0.1 0 0\n"
                      << bad << "\n"
                      << "EDGE_SE2 0 1 0.1 0 0 1e6 0 0 1e6 0 1e4\n";
  try {
    ReadG2o(file);
    ADD_FAILURE() << "accepted: " << bad;
  } catch (const core::Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("bad.g2o:" + std::to_string(line) + ":"), std::string::npos) << what;
    EXPECT_NE(what.find(reason), std::string::npos) << what;
  }
}

TEST(PoseGraph, AMalformedG2oFileIsRejectedNamingFileAndLine) {
  ExpectRejectedAtLine("VERTEX_SE2 2 0.2 zero 0", 4, "'zero' is not a finite number");
  ExpectRejectedAtLine("VERTEX_SE2 2 0.2 0", 4, "VERTEX_SE2 takes");
  ExpectRejectedAtLine("VERTEX_SE2 1 0.2 0 0", 4, "node 1 is defined twice");
  ExpectRejectedAtLine("VERTEX_SE2 -2 0.2 0 0", 4, "not a node id");
  ExpectRejectedAtLine("EDGE_SE2 0 1 0.1 0 0 1e6 0 0 1e6 0", 4, "EDGE_SE2 takes");
  ExpectRejectedAtLine("EDGE_SE2 0 1 0.1 0 0 -1 0 0 1e6 0 1e4", 4, "not positive definite");
  ExpectRejectedAtLine("EDGE_SE2 0 1 0.1 0 nan 1e6 0 0 1e6 0 1e4", 4, "not a finite number");
  ExpectRejectedAtLine("EDGE_SE2 0 7 0.1 0 0 1e6 0 0 1e6 0 1e4", 4, "does not join two defined nodes");
  ExpectRejectedAtLine("FIX 9", 4, "no such node");
  ExpectRejectedAtLine("VERTEX_SE3:QUAT 2 0 0 0 0 0 0 1", 4, "unknown record");
  ExpectRejectedAtLine("VERTEX_SE2 3 0.2 0 0", 4, "node 2 is missing");
}

TEST(PoseGraph, AnUnreadableOrEmptyG2oFileIsRejected) {
  test::ScratchDir scratch;
  EXPECT_THROW(ReadG2o(scratch.path() / "absent.g2o"), core::Error);
  std::ofstream(scratch.path() / "empty.g2o") << "# nothing\n";
  EXPECT_THROW(ReadG2o(scratch.path() / "empty.g2o"), core::Error);
}

}  // namespace
}  // namespace mosaicloc::mapping
