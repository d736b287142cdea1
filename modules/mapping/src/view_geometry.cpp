#include "mosaicloc/mapping/view_geometry.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/LU>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>

#include "mosaicloc/core/error.hpp"

namespace mosaicloc::mapping {

bool ViewGeometryOptions::Check(std::string* why) const {
  const auto fail = [why](const char* message) {
    if (why != nullptr) *why = message;
    return false;
  };
  if (!(tilt_step_sigma_rad > 0.0 && height_step_sigma > 0.0 && tilt_prior_sigma_rad > 0.0 &&
        height_prior_sigma > 0.0 && min_observation_sigma > 0.0)) {
    return fail("view geometry: the sigmas must be positive");
  }
  if (!(min_agreement >= -1.0 && min_agreement <= 1.0)) return fail("view geometry: min_agreement must be in [-1, 1]");
  return true;
}

std::optional<ViewObservation> ObserveView(const tracking::TrackResult& registration, const camera::IdealCamera& camera,
                                           int earlier, int later, int min_templates) {
  if (!registration.ok()) return std::nullopt;
  const Eigen::Vector2d centre(camera.cx(), camera.cy());
  // w = t + A c + c (m.c) over the inlier templates (c: the later frame's template centre about
  // its image centre, w: where it lies in the earlier frame, about its centre): a homography to
  // second order. The templates lie in the overlap, to one side of the centre on a long step,
  // so the second-order terms (the two views' tilts against each other) must be fitted for A,
  // the map's derivative at the centre, to be unbiased by them. Unknowns: a00 a01 a10 a11 tx ty mx my.
  std::vector<std::pair<Eigen::Vector2d, Eigen::Vector2d>> points;
  for (const tracking::TemplateReport& t : registration.templates) {
    if (!t.inlier || !t.refined.ok()) continue;
    const cv::Rect& r = t.spot.rect;
    points.emplace_back(Eigen::Vector2d(r.x + 0.5 * (r.width - 1), r.y + 0.5 * (r.height - 1)) - centre,
                        t.refined.centre_raster - centre);
  }
  const int count = static_cast<int>(points.size());
  if (count < std::max(min_templates, 5)) return std::nullopt;
  // Scaled to about 1 for the normal equations' conditioning.
  const double unit = std::max(camera.width_px(), camera.height_px()) / 2.0;
  Eigen::Matrix<double, 8, 8> jtj = Eigen::Matrix<double, 8, 8>::Zero();
  Eigen::Matrix<double, 8, 1> jtw = Eigen::Matrix<double, 8, 1>::Zero();
  const auto rows = [unit](const Eigen::Vector2d& c_px) {
    const Eigen::Vector2d c = c_px / unit;
    Eigen::Matrix<double, 2, 8> j;
    j << c.x(), c.y(), 0, 0, 1, 0, c.x() * c.x(), c.x() * c.y(),  //
        0, 0, c.x(), c.y(), 0, 1, c.x() * c.y(), c.y() * c.y();
    return j;
  };
  for (const auto& [c, w] : points) {
    const Eigen::Matrix<double, 2, 8> j = rows(c);
    jtj += j.transpose() * j;
    jtw += j.transpose() * (w / unit);
  }
  const Eigen::FullPivLU<Eigen::Matrix<double, 8, 8>> lu(jtj);
  if (lu.rank() < 8) return std::nullopt;  // the templates do not determine it
  const Eigen::Matrix<double, 8, 8> inverse = lu.inverse();
  const Eigen::Matrix<double, 8, 1> x = inverse * jtw;
  double rss = 0.0;
  for (const auto& [c, w] : points) rss += (rows(c) * x - w / unit).squaredNorm();
  Eigen::Matrix2d a;
  a << x(0), x(1), x(2), x(3);
  const Eigen::Vector2d step = unit * Eigen::Vector2d(x(4), x(5));
  // The later frame's rotation taken off: A R(-theta).
  const double theta = std::atan2(a(1, 0) - a(0, 1), a(0, 0) + a(1, 1));
  Eigen::Matrix2d unrotate;
  unrotate << std::cos(theta), std::sin(theta), -std::sin(theta), std::cos(theta);
  const Eigen::Matrix2d b = a * unrotate;
  const double isotropic = 0.5 * (b(0, 0) + b(1, 1));
  if (!(isotropic > 0.0)) return std::nullopt;
  ViewObservation o;
  o.earlier = earlier;
  o.later = later;
  o.step_px = step;
  o.log_scale = std::log(isotropic);
  o.anisotropy = Eigen::Vector2d(0.5 * (b(0, 0) - b(1, 1)), 0.5 * (b(0, 1) + b(1, 0)));
  // The residual's variance per coordinate (2 count equations, 8 unknowns), and the variance
  // of a half-sum or half-difference of two of A's entries (their covariance left out).
  const double variance = rss / std::max(2 * count - 8, 1);
  o.sigma = std::sqrt(variance * 0.25 * std::max(inverse(0, 0) + inverse(3, 3), inverse(1, 1) + inverse(2, 2)));
  return o;
}

namespace {

// Unknowns of the solve: log-height of frame i at i, its tilt at frames + 2i (x) and
// frames + 2i + 1 (y).
int HeightAt(int i) { return i; }
int TiltAt(int frames, int i, int axis) { return frames + 2 * i + axis; }
// The heights' agreement is that of their changes over this many frames.
constexpr int kHeightLag = 20;

// The least-squares solution from `observations` (see SolveViewGeometry); none when the solve
// fails (it cannot with the priors).
std::optional<Eigen::VectorXd> Solve(const std::vector<const ViewObservation*>& observations, int frames, double h,
                                     const ViewGeometryOptions& options, const std::vector<char>& starts_drive) {
  const auto height_at = HeightAt;
  const auto tilt_at = [frames](int i, int axis) { return TiltAt(frames, i, axis); };
  const int unknowns = 3 * frames;
  // The observations' equations: terms, value and sigma each.
  struct Equation {
    std::vector<std::pair<int, double>> terms;
    double value = 0.0;
    double sigma = 1.0;
  };
  std::vector<Equation> equations;
  equations.reserve(3 * observations.size());
  for (const ViewObservation* p : observations) {
    const ViewObservation& o = *p;
    if (o.earlier < 0 || o.later < 0 || o.earlier >= frames || o.later >= frames) continue;
    const double dx = o.step_px.x(), dy = o.step_px.y();
    const double sigma = std::max(o.sigma, options.min_observation_sigma);
    const int ax = tilt_at(o.earlier, 0), ay = tilt_at(o.earlier, 1);
    // log k_later - log k_earlier - 1.5 n.step / h = log scale
    equations.push_back({{{height_at(o.later), 1.0}, {height_at(o.earlier), -1.0}, {ax, -1.5 * dx / h}, {ay, -1.5 * dy / h}},
                         o.log_scale, sigma});
    // p = -(dx nx - dy ny) / 2h, q = -(dy nx + dx ny) / 2h
    equations.push_back({{{ax, -dx / (2 * h)}, {ay, dy / (2 * h)}}, o.anisotropy.x(), sigma});
    equations.push_back({{{ax, -dy / (2 * h)}, {ay, -dx / (2 * h)}}, o.anisotropy.y(), sigma});
  }
  // The least-squares solution with the observations' sigmas times `inflate`.
  const auto solve = [&](double inflate) -> std::optional<Eigen::VectorXd> {
    std::vector<Eigen::Triplet<double>> normal;
    Eigen::VectorXd rhs = Eigen::VectorXd::Zero(unknowns);
    const auto add = [&](const std::vector<std::pair<int, double>>& terms, double value, double sigma) {
      const double w = 1.0 / (sigma * sigma);
      for (const auto& [i, ci] : terms) {
        rhs(i) += w * ci * value;
        for (const auto& [j, cj] : terms) normal.emplace_back(i, j, w * ci * cj);
      }
    };
    for (const Equation& e : equations) add(e.terms, e.value, inflate * e.sigma);
    for (int i = 0; i < frames; ++i) {
      add({{height_at(i), 1.0}}, 0.0, options.height_prior_sigma);
      add({{tilt_at(i, 0), 1.0}}, 0.0, options.tilt_prior_sigma_rad);
      add({{tilt_at(i, 1), 1.0}}, 0.0, options.tilt_prior_sigma_rad);
      if (i == 0 || starts_drive[static_cast<std::size_t>(i)]) continue;
      add({{height_at(i), 1.0}, {height_at(i - 1), -1.0}}, 0.0, options.height_step_sigma);
      add({{tilt_at(i, 0), 1.0}, {tilt_at(i - 1, 0), -1.0}}, 0.0, options.tilt_step_sigma_rad);
      add({{tilt_at(i, 1), 1.0}, {tilt_at(i - 1, 1), -1.0}}, 0.0, options.tilt_step_sigma_rad);
    }
    Eigen::SparseMatrix<double> matrix(unknowns, unknowns);
    matrix.setFromTriplets(normal.begin(), normal.end());  // duplicates are summed
    const Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(matrix);
    if (solver.info() != Eigen::Success) return std::nullopt;  // cannot happen with the priors
    Eigen::VectorXd x = solver.solve(rhs);
    if (solver.info() != Eigen::Success) return std::nullopt;
    return x;
  };
  std::optional<Eigen::VectorXd> x = solve(1.0);
  if (!x) return std::nullopt;
  // The fits' sigmas come from a handful of templates each and miss what is common to them:
  // scaled by the observations' a-posteriori variance factor where it exceeds 1, so that the
  // frames' smoothness weighs as much as the observations deserve.
  double chi2 = 0.0;
  for (const Equation& e : equations) {
    double r = -e.value;
    for (const auto& [i, c] : e.terms) r += c * (*x)(i);
    chi2 += (r / e.sigma) * (r / e.sigma);
  }
  const double factor = equations.empty() ? 1.0 : chi2 / static_cast<double>(equations.size());
  if (factor > 1.0) {
    if (auto again = solve(std::sqrt(factor))) x = std::move(again);
  }
  return x;
}

// Pearson's correlation of two solutions' unknowns first, first + stride, ... (count of them),
// or with lag > 1 of their changes over non-overlapping runs of `lag` of them (the heights are
// chained from relative scales: two independent random walks correlate by chance far more
// than their steps do); 0 where either does not vary.
double Agreement(const Eigen::VectorXd& a, const Eigen::VectorXd& b, int first, int stride, int count, int lag = 1) {
  std::vector<double> va, vb;
  if (lag <= 1) {
    for (int k = 0; k < count; ++k) va.push_back(a(first + k * stride)), vb.push_back(b(first + k * stride));
  } else {
    for (int k = 0; k + lag < count; k += lag) {
      va.push_back(a(first + (k + lag) * stride) - a(first + k * stride));
      vb.push_back(b(first + (k + lag) * stride) - b(first + k * stride));
    }
  }
  const auto n = static_cast<double>(va.size());
  if (va.size() < 3) return 0.0;
  double ma = 0.0, mb = 0.0;
  for (std::size_t k = 0; k < va.size(); ++k) ma += va[k], mb += vb[k];
  ma /= n, mb /= n;
  double sab = 0.0, saa = 0.0, sbb = 0.0;
  for (std::size_t k = 0; k < va.size(); ++k) {
    const double da = va[k] - ma, db = vb[k] - mb;
    sab += da * db, saa += da * da, sbb += db * db;
  }
  return saa > 0.0 && sbb > 0.0 ? sab / std::sqrt(saa * sbb) : 0.0;
}

}  // namespace

ViewGeometry SolveViewGeometry(const std::vector<ViewObservation>& observations, int frames,
                               const camera::IdealCamera& camera, double camera_height_mm,
                               const ViewGeometryOptions& options, const std::vector<int>& drive_starts) {
  std::string why;
  if (!options.Check(&why)) core::ThrowInvalidInput(why);
  if (!(camera_height_mm > 0.0)) core::ThrowInvalidInput("view geometry: the camera height must be positive");
  ViewGeometry geometry;
  geometry.scale.assign(static_cast<std::size_t>(std::max(frames, 0)), 1.0);
  geometry.tilt.assign(static_cast<std::size_t>(std::max(frames, 0)), Eigen::Vector2d::Zero());
  if (frames <= 0) return geometry;
  const double h = camera_height_mm / camera.mm_per_px();
  std::vector<char> starts_drive(static_cast<std::size_t>(frames), 0);
  for (const int first : drive_starts) {
    if (first >= 0 && first < frames) starts_drive[static_cast<std::size_t>(first)] = 1;
  }
  std::vector<const ViewObservation*> all, consecutive, longer;
  for (const ViewObservation& o : observations) {
    all.push_back(&o);
    (o.later == o.earlier + 1 ? consecutive : longer).push_back(&o);
  }
  const std::optional<Eigen::VectorXd> x = Solve(all, frames, h, options, starts_drive);
  if (!x) return geometry;  // keep the calibrated height and no tilt
  // Is there anything to correct? The registrations to the previous frame and the longer ones
  // (keyframes, loops) measure the same floor with errors of their own: where the two solutions
  // agree, the floor's height and tilt show; on a flat floor they are noise that would only bend
  // the map, and what a frame's templates bias alike in both is not common enough to agree.
  const std::optional<Eigen::VectorXd> a = Solve(consecutive, frames, h, options, starts_drive);
  const std::optional<Eigen::VectorXd> b = Solve(longer, frames, h, options, starts_drive);
  if (a && b) {
    geometry.height_agreement = Agreement(*a, *b, HeightAt(0), 1, frames, kHeightLag);
    geometry.tilt_agreement = Eigen::Vector2d(Agreement(*a, *b, TiltAt(frames, 0, 0), 2, frames),
                                              Agreement(*a, *b, TiltAt(frames, 0, 1), 2, frames));
  }
  // Noise agrees by chance over few values: a correlation r of n independent ones counts where
  // its t statistic r sqrt((n - 2) / (1 - r^2)) is 3 or more (about one independent tilt per 10
  // frames, one height change per run of kHeightLag).
  const auto shows = [&options](double r, double n) {
    if (!(r >= options.min_agreement) || n <= 2.0) return false;
    return r >= 1.0 || r * std::sqrt((n - 2.0) / (1.0 - r * r)) >= 3.0;
  };
  geometry.height_applied = shows(geometry.height_agreement, frames / static_cast<double>(kHeightLag));
  geometry.tilt_applied = shows(geometry.tilt_agreement.minCoeff(), frames / 10.0);
  for (int i = 0; i < frames; ++i) {
    if (geometry.height_applied) geometry.scale[i] = std::exp((*x)(HeightAt(i)));
    if (geometry.tilt_applied) geometry.tilt[i] = Eigen::Vector2d((*x)(TiltAt(frames, i, 0)), (*x)(TiltAt(frames, i, 1)));
  }
  return geometry;
}

core::Pose2 CorrectRegistration(const core::Pose2& earlier_T_later, const ViewObservation& observation,
                                const ViewGeometry& geometry, const camera::IdealCamera& camera,
                                double camera_height_mm) {
  const auto e = static_cast<std::size_t>(observation.earlier);
  const double h = camera_height_mm / camera.mm_per_px();
  const Eigen::Vector2d& n = geometry.tilt[e];
  const Eigen::Vector2d& d = observation.step_px;
  // The registration's rotation carries (step x n) / 2h in image axes (y down): the camera
  // frame's yaw is the image rotation's negative.
  const double yaw_bias = (d.x() * n.y() - d.y() * n.x()) / (2.0 * h);
  const Eigen::Vector2d t = geometry.scale[e] * earlier_T_later.translation_mm();
  return core::Pose2(t.x(), t.y(), earlier_T_later.yaw_rad() + yaw_bias);
}

}  // namespace mosaicloc::mapping
