#include "mosaicloc/mapping/pose_graph.hpp"

#include <chrono>
#include <cmath>
#include <fstream>
#include <iomanip>
#include <map>
#include <numbers>
#include <sstream>

#include <Eigen/Cholesky>
#include <Eigen/CholmodSupport>
#include <Eigen/SparseCore>
#include <ceres/ceres.h>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/core/file.hpp"

namespace mosaicloc::mapping {
namespace {

// An angle wrapped to [-pi, pi), for doubles and Ceres' Jets alike.
template <typename T>
T Wrapped(const T& angle) {
  const T two_pi(2.0 * std::numbers::pi);
  using std::floor;
  return angle - two_pi * floor((angle + T(std::numbers::pi)) / two_pi);
}

// The residual of pose_graph_2d: the measured pose of b in a's frame against the estimated
// one, whitened by the square root of the information.
class EdgeCost {
 public:
  EdgeCost(const core::Pose2& a_from_b, const Eigen::Matrix3d& sqrt_information)
      : a_from_b_(a_from_b), sqrt_information_(sqrt_information) {}

  /// a and b: a node's (x mm, y mm, yaw rad), one parameter block.
  template <typename T>
  bool operator()(const T* a, const T* b, T* residual) const {
    using std::cos;
    using std::sin;
    const T c = cos(a[2]), s = sin(a[2]);
    const T dx = b[0] - a[0], dy = b[1] - a[1];
    Eigen::Matrix<T, 3, 1> r;
    r(0) = c * dx + s * dy - T(a_from_b_.x_mm());
    r(1) = -s * dx + c * dy - T(a_from_b_.y_mm());
    r(2) = Wrapped(b[2] - a[2] - T(a_from_b_.yaw_rad()));
    Eigen::Map<Eigen::Matrix<T, 3, 1>> whitened(residual);
    whitened = sqrt_information_.cast<T>() * r;
    return true;
  }

 private:
  core::Pose2 a_from_b_;
  Eigen::Matrix3d sqrt_information_;
};

// Upper-triangular S with Sᵀ S = information; throws when it is not positive definite.
Eigen::Matrix3d SqrtInformation(const PoseGraphEdge& edge) {
  const Eigen::Matrix3d& information = edge.information;
  if (!information.allFinite() || (information - information.transpose()).cwiseAbs().maxCoeff() >
                                      1e-9 * information.cwiseAbs().maxCoeff()) {
    core::ThrowInvalidInput("pose graph: edge " + std::to_string(edge.from) + "-" + std::to_string(edge.to) +
                            ": the information matrix is not symmetric");
  }
  const Eigen::LLT<Eigen::Matrix3d> llt(information);
  if (llt.info() != Eigen::Success) {
    core::ThrowInvalidInput("pose graph: edge " + std::to_string(edge.from) + "-" + std::to_string(edge.to) +
                            ": the information matrix is not positive definite");
  }
  return llt.matrixU();
}

void CheckNodes(const PoseGraph& graph, const PoseGraphEdge& edge) {
  const int n = static_cast<int>(graph.nodes.size());
  if (edge.from < 0 || edge.from >= n || edge.to < 0 || edge.to >= n || edge.from == edge.to) {
    core::ThrowInvalidInput("pose graph: edge " + std::to_string(edge.from) + "-" + std::to_string(edge.to) +
                            " does not join two of the " + std::to_string(n) + " nodes");
  }
}

// The first line of a graph this code wrote.
constexpr const char* kHeader = "# mosaicloc pose graph";

// g2o's SE2 error is the measured pose's inverse times the predicted relative pose: its
// translation is ours (in the `from` node's frame) turned by the measured yaw. J maps ours to
// g2o's, so an information matrix is J Ω Jᵀ in g2o's frame and Jᵀ Ω J back.
Eigen::Matrix3d G2oFromOurs(const core::Pose2& measured) {
  const double c = std::cos(measured.yaw_rad()), s = std::sin(measured.yaw_rad());
  Eigen::Matrix3d J = Eigen::Matrix3d::Identity();
  J.topLeftCorner<2, 2>() << c, s, -s, c;  // R(yaw)ᵀ
  return J;
}

int Root(std::vector<int>& parent, int i) {
  while (parent[i] != i) i = parent[i] = parent[parent[i]];
  return i;
}

// Solves A x = b for the free nodes (index[i] >= 0); false if A is not positive definite.
// CHOLMOD's supernodal factorization (the one Ceres uses): on the 10^5-node survey graph of
// mosaicloc_pose_graph_benchmark it takes the linear start from 4.9-6.5 s (Eigen's simplicial
// LDLT) to 3.0-3.6 s.
bool SolveSparse(int size, std::vector<Eigen::Triplet<double>>& triplets, const Eigen::VectorXd& b,
                 Eigen::VectorXd* x) {
  Eigen::SparseMatrix<double> a(size, size);
  a.setFromTriplets(triplets.begin(), triplets.end());
  const Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>> llt(a);
  if (llt.info() != Eigen::Success) return false;
  *x = llt.solve(b);
  return llt.info() == Eigen::Success && x->allFinite();
}

// A start near the optimum, so that the nonlinear solve needs few iterations (the two linear
// steps of Carlone et al.'s LAGO): first the yaws alone, a linear least-squares correction of
// each edge's yaw error weighted by its yaw variance; then, the yaws fixed, the positions,
// whose error is linear in them. Held nodes stay. Robust losses are not applied here: the
// nonlinear solve that follows applies them. Leaves the poses unchanged if a system is singular.
bool LinearInitialization(const PoseGraph& graph, const std::vector<char>& constant, std::vector<double>& poses) {
  const int n = static_cast<int>(graph.nodes.size());
  std::vector<int> index(static_cast<std::size_t>(n), -1);
  int m = 0;
  for (int i = 0; i < n; ++i) {
    if (!constant[i]) index[i] = m++;
  }
  if (m == 0) return false;
  std::vector<Eigen::Triplet<double>> triplets;
  // Yaws: Δ_to − Δ_from = wrap(measured − (θ_to − θ_from)), weight 1 / σ²_yaw.
  Eigen::VectorXd b = Eigen::VectorXd::Zero(m);
  for (const PoseGraphEdge& e : graph.edges) {
    const double w = 1.0 / e.information.inverse()(2, 2);
    const double r = Wrapped(e.from_T_to.yaw_rad() - (poses[3 * e.to + 2] - poses[3 * e.from + 2]));
    const int f = index[e.from], t = index[e.to];
    if (f >= 0) triplets.emplace_back(f, f, w), b(f) -= w * r;
    if (t >= 0) triplets.emplace_back(t, t, w), b(t) += w * r;
    if (f >= 0 && t >= 0) triplets.emplace_back(f, t, -w), triplets.emplace_back(t, f, -w);
  }
  Eigen::VectorXd dyaw;
  if (!SolveSparse(m, triplets, b, &dyaw)) return false;
  std::vector<double> new_yaws(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) {
    new_yaws[i] = index[i] >= 0 ? Wrapped(poses[3 * i + 2] + dyaw(index[i])) : poses[3 * i + 2];
  }
  // Positions: p_to − p_from = R(θ_from) t, weight R W Rᵀ with W the translation's information
  // (the inverse of its marginal covariance).
  triplets.clear();
  b = Eigen::VectorXd::Zero(2 * m);
  for (const PoseGraphEdge& e : graph.edges) {
    const double c = std::cos(new_yaws[e.from]), s = std::sin(new_yaws[e.from]);
    Eigen::Matrix2d rotation;
    rotation << c, -s, s, c;
    const Eigen::Matrix2d w =
        rotation * Eigen::Matrix2d(e.information.inverse().topLeftCorner<2, 2>()).inverse() * rotation.transpose();
    const Eigen::Vector2d d = rotation * e.from_T_to.translation_mm();
    const Eigen::Vector2d p_from(poses[3 * e.from], poses[3 * e.from + 1]);
    const Eigen::Vector2d p_to(poses[3 * e.to], poses[3 * e.to + 1]);
    const int f = index[e.from], t = index[e.to];
    // Unknowns are the free nodes' positions; a held node's is a constant on the right.
    Eigen::Vector2d rhs = d;
    if (f < 0) rhs += p_from;
    if (t < 0) rhs -= p_to;
    const Eigen::Vector2d wr = w * rhs;
    for (int r = 0; r < 2; ++r) {
      for (int k = 0; k < 2; ++k) {
        if (f >= 0) triplets.emplace_back(2 * f + r, 2 * f + k, w(r, k));
        if (t >= 0) triplets.emplace_back(2 * t + r, 2 * t + k, w(r, k));
        if (f >= 0 && t >= 0) {
          triplets.emplace_back(2 * f + r, 2 * t + k, -w(r, k));
          triplets.emplace_back(2 * t + r, 2 * f + k, -w(r, k));
        }
      }
      if (t >= 0) b(2 * t + r) += wr(r);
      if (f >= 0) b(2 * f + r) -= wr(r);
    }
  }
  Eigen::VectorXd p;
  if (!SolveSparse(2 * m, triplets, b, &p)) return false;
  for (int i = 0; i < n; ++i) {
    if (index[i] < 0) continue;
    poses[3 * i] = p(2 * index[i]);
    poses[3 * i + 1] = p(2 * index[i] + 1);
    poses[3 * i + 2] = new_yaws[i];
  }
  return true;
}

}  // namespace

const char* ToString(EdgeKind kind) { return kind == EdgeKind::kLoop ? "loop" : "sequential"; }

Eigen::Vector3d EdgeResidual(const PoseGraph& graph, const PoseGraphEdge& edge) {
  CheckNodes(graph, edge);
  const core::Pose2& a = graph.nodes[edge.from];
  const core::Pose2& b = graph.nodes[edge.to];
  const double pose_a[3] = {a.x_mm(), a.y_mm(), a.yaw_rad()}, pose_b[3] = {b.x_mm(), b.y_mm(), b.yaw_rad()};
  Eigen::Vector3d residual;
  EdgeCost(edge.from_T_to, SqrtInformation(edge))(pose_a, pose_b, residual.data());
  return residual;
}

OptimizeReport Optimize(PoseGraph& graph, const OptimizeOptions& options) {
  const auto started = std::chrono::steady_clock::now();
  const int n = static_cast<int>(graph.nodes.size());
  // One parameter block of (x mm, y mm, yaw rad) a node. The yaw needs no manifold: the
  // residual wraps the yaw difference, and the pose written back wraps the yaw.
  std::vector<double> poses(3 * static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) {
    poses[3 * i] = graph.nodes[i].x_mm();
    poses[3 * i + 1] = graph.nodes[i].y_mm();
    poses[3 * i + 2] = graph.nodes[i].yaw_rad();
  }
  ceres::Problem::Options problem_options;
  ceres::Problem problem(problem_options);
  std::vector<int> parent(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) parent[i] = i;
  std::vector<char> used(static_cast<std::size_t>(n), 0);
  for (const PoseGraphEdge& edge : graph.edges) {
    CheckNodes(graph, edge);
    auto* cost = new ceres::AutoDiffCostFunction<EdgeCost, 3, 3, 3>(
        new EdgeCost(edge.from_T_to, SqrtInformation(edge)));
    ceres::LossFunction* loss =
        edge.kind == EdgeKind::kLoop && options.loop_huber_sigmas > 0.0 ? new ceres::HuberLoss(options.loop_huber_sigmas)
                                                                         : nullptr;
    problem.AddResidualBlock(cost, loss, &poses[3 * edge.from], &poses[3 * edge.to]);
    parent[Root(parent, edge.from)] = Root(parent, edge.to);
    used[edge.from] = used[edge.to] = 1;
  }
  OptimizeReport report;
  std::vector<char> held(static_cast<std::size_t>(n), 0), constant(static_cast<std::size_t>(n), 0);
  for (const int f : graph.fixed) {
    if (f < 0 || f >= n) core::ThrowInvalidInput("pose graph: fixed node " + std::to_string(f) + " does not exist");
    held[Root(parent, f)] = 1;
    constant[f] = 1;
    if (used[f]) problem.SetParameterBlockConstant(&poses[3 * f]);
  }
  // Each connected piece once: its first node is held when no fixed node holds it.
  std::vector<char> counted(static_cast<std::size_t>(n), 0);
  for (int i = 0; i < n; ++i) {
    if (!used[i]) continue;
    const int root = Root(parent, i);
    if (counted[root]) continue;
    counted[root] = 1;
    ++report.pieces;
    if (!held[root]) {
      constant[i] = 1;
      problem.SetParameterBlockConstant(&poses[3 * i]);
    }
  }
  if (options.linear_initialization && problem.NumResidualBlocks() > 0) {
    const auto initialization_started = std::chrono::steady_clock::now();
    report.initialized = LinearInitialization(graph, constant, poses);
    report.initialization_seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - initialization_started).count();
  }
  if (problem.NumResidualBlocks() == 0) {
    report.converged = true;
    return report;
  }
  ceres::Solver::Options solver;
  solver.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  solver.max_num_iterations = options.max_iterations;
  // From the linear estimate the first steps are Gauss-Newton's: Levenberg-Marquardt's default
  // damping would creep the last per cent of the cost down over ten iterations instead of three.
  if (report.initialized) solver.initial_trust_region_radius = 1e12;
  solver.num_threads = options.threads;
  solver.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(solver, &problem, &summary);
  report.converged = summary.termination_type == ceres::CONVERGENCE;
  report.iterations = static_cast<int>(summary.iterations.size());
  report.initial_cost = summary.initial_cost;
  report.final_cost = summary.final_cost;
  report.message = summary.message;
  if (summary.IsSolutionUsable()) {
    for (int i = 0; i < n; ++i) graph.nodes[i] = core::Pose2(poses[3 * i], poses[3 * i + 1], Wrapped(poses[3 * i + 2]));
  }
  report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  return report;
}

void WriteG2o(const std::filesystem::path& file, const PoseGraph& graph) {
  std::ostringstream out;
  out << std::setprecision(17);
  out << kHeader << ": metres, radians; information in metres, in g2o's error frame; '# loop' marks each loop "
         "closure's edge\n";
  for (std::size_t i = 0; i < graph.nodes.size(); ++i) {
    const core::Pose2& p = graph.nodes[i];
    out << "VERTEX_SE2 " << i << ' ' << p.x_mm() * 1e-3 << ' ' << p.y_mm() * 1e-3 << ' ' << p.yaw_rad() << '\n';
  }
  for (const int f : graph.fixed) out << "FIX " << f << '\n';
  // Information in metres: the position rows and columns scale by 1000 each.
  const Eigen::Vector3d to_m(1e3, 1e3, 1.0);
  for (const PoseGraphEdge& e : graph.edges) {
    const Eigen::Matrix3d J = G2oFromOurs(e.from_T_to);
    const Eigen::Matrix3d info = to_m.asDiagonal() * (J * e.information * J.transpose()) * to_m.asDiagonal();
    if (e.kind == EdgeKind::kLoop) out << "# loop\n";
    out << "EDGE_SE2 " << e.from << ' ' << e.to << ' ' << e.from_T_to.x_mm() * 1e-3 << ' '
        << e.from_T_to.y_mm() * 1e-3 << ' ' << e.from_T_to.yaw_rad() << ' ' << info(0, 0) << ' ' << info(0, 1)
        << ' ' << info(0, 2) << ' ' << info(1, 1) << ' ' << info(1, 2) << ' ' << info(2, 2) << '\n';
  }
  core::WriteFileAtomically(file, out.str());
}

PoseGraph ReadG2o(const std::filesystem::path& file) {
  std::ifstream in(file);
  if (!in) core::ThrowInvalidInput(file.string() + ": cannot be read");
  std::map<long, std::pair<core::Pose2, int>> vertices;  // id: pose, line
  PoseGraph graph;
  std::vector<int> edge_lines;
  std::vector<std::pair<long, int>> fixed;  // id, line
  std::string line;
  int number = 0;
  bool marked = false;  // a file of ours: loops are marked, not guessed from the node ids
  bool loop_next = false;
  auto fail_at = [&](int at, const std::string& why) {
    core::ThrowInvalidInput(file.string() + ":" + std::to_string(at) + ": " + why);
  };
  auto fail = [&](const std::string& why) { fail_at(number, why); };
  while (std::getline(in, line)) {
    ++number;
    std::istringstream fields(line);
    std::string tag;
    if (!(fields >> tag)) continue;
    if (tag[0] == '#') {
      marked = marked || line.rfind(kHeader, 0) == 0;
      loop_next = marked && line == "# loop";
      continue;
    }
    const bool is_loop_marked = loop_next;
    loop_next = false;
    std::vector<double> v;
    std::string word;
    while (fields >> word) {
      try {
        std::size_t used = 0;
        v.push_back(std::stod(word, &used));
        if (used != word.size() || !std::isfinite(v.back())) throw std::invalid_argument(word);
      } catch (const std::exception&) {
        fail("'" + word + "' is not a finite number");
      }
    }
    auto id = [&](double value) {
      if (value < 0 || value != std::floor(value) || value > 1e9) fail("'" + std::to_string(value) + "' is not a node id");
      return static_cast<long>(value);
    };
    if (tag == "VERTEX_SE2") {
      if (v.size() != 4) fail("VERTEX_SE2 takes an id, x, y and theta");
      if (!vertices.emplace(id(v[0]), std::pair(core::Pose2(v[1] * 1e3, v[2] * 1e3, v[3]), number)).second) {
        fail("node " + std::to_string(id(v[0])) + " is defined twice");
      }
    } else if (tag == "EDGE_SE2") {
      if (v.size() != 11) fail("EDGE_SE2 takes two ids, dx, dy, dtheta and six information entries");
      PoseGraphEdge e;
      e.from = static_cast<int>(id(v[0]));
      e.to = static_cast<int>(id(v[1]));
      e.from_T_to = core::Pose2(v[2] * 1e3, v[3] * 1e3, v[4]);
      Eigen::Matrix3d info;
      info << v[5], v[6], v[7], v[6], v[8], v[9], v[7], v[9], v[10];
      const Eigen::Vector3d to_mm(1e-3, 1e-3, 1.0);
      const Eigen::Matrix3d J = G2oFromOurs(e.from_T_to);
      e.information = J.transpose() * (to_mm.asDiagonal() * info * to_mm.asDiagonal()) * J;
      if (Eigen::LLT<Eigen::Matrix3d>(e.information).info() != Eigen::Success) {
        fail("the information matrix is not positive definite");
      }
      const bool loop = marked ? is_loop_marked : std::abs(e.to - e.from) != 1;
      e.kind = loop ? EdgeKind::kLoop : EdgeKind::kSequential;
      graph.edges.push_back(e);
      edge_lines.push_back(number);
    } else if (tag == "FIX") {
      if (v.size() != 1) fail("FIX takes one id");
      fixed.emplace_back(id(v[0]), number);
    } else {
      fail("unknown record '" + tag + "' (VERTEX_SE2, EDGE_SE2 and FIX are read)");
    }
  }
  if (vertices.empty()) core::ThrowInvalidInput(file.string() + ": no VERTEX_SE2");
  long expected = 0;
  for (const auto& [node, vertex] : vertices) {
    if (node != expected) {
      fail_at(vertex.second, "node " + std::to_string(expected) + " is missing (nodes must be numbered 0 to n-1)");
    }
    graph.nodes.push_back(vertex.first);
    ++expected;
  }
  for (std::size_t i = 0; i < graph.edges.size(); ++i) {
    const PoseGraphEdge& e = graph.edges[i];
    if (e.from >= expected || e.to >= expected || e.from == e.to) {
      fail_at(edge_lines[i], "edge " + std::to_string(e.from) + "-" + std::to_string(e.to) +
                                 " does not join two defined nodes");
    }
  }
  for (const auto& [f, at] : fixed) {
    if (f >= expected) fail_at(at, "FIX " + std::to_string(f) + ": no such node");
    graph.fixed.push_back(static_cast<int>(f));
  }
  return graph;
}

}  // namespace mosaicloc::mapping
