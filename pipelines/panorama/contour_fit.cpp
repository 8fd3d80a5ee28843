#include "pipelines/panorama/contour_fit.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

namespace fluoro {
namespace {

// The first contour as local lines: each vertex's neighbourhood (15 points either side, some
// 30 px of a livewire trace, short against the bends of a bone's outline) fitted by its principal
// direction, which averages the tracing jitter that would tilt a single segment; what jitter is
// left in the direction is kept (`tilt_var`), since a tilted normal fakes information along the
// translation.
struct LocalLine {
  Eigen::Vector2d point, normal;
  double tilt_var = 0;  // variance of the direction's angle (rad^2) from the fit's residuals
};

std::vector<LocalLine> local_lines(const std::vector<Eigen::Vector2d>& c) {
  std::vector<LocalLine> out;
  const int n = int(c.size()), h = 15;
  for (int k = h; k + h < n; ++k) {
    Eigen::Vector2d m = Eigen::Vector2d::Zero();
    for (int j = k - h; j <= k + h; ++j) m += c[size_t(j)];
    m /= 2 * h + 1;
    Eigen::Matrix2d S = Eigen::Matrix2d::Zero();
    for (int j = k - h; j <= k + h; ++j) S += (c[size_t(j)] - m) * (c[size_t(j)] - m).transpose();
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> e(S);
    // Across the contour: the smallest spread; the slope's variance of a line fit,
    // residual variance over the spread along it.
    const double across = e.eigenvalues()(0) / (2 * h - 1), along = std::max(e.eigenvalues()(1), 1e-12);
    out.push_back({m, e.eigenvectors().col(0), across / along});
  }
  return out;
}

struct Match {
  double d, J;  // signed distance across the first contour, its derivative in the scale
  double J_noise;  // the part of J^2 the local line's tilt alone would give, on average
};

// Points q = p + scale t that land within reach of an inner vertex of the first contour (not
// beyond its ends, where the nearest vertex is the end one).
std::vector<Match> matches(const std::vector<LocalLine>& lines, const std::vector<Eigen::Vector2d>& p,
                           const Eigen::Vector2d& t, double scale) {
  std::vector<Match> out;
  const double reach = 2.0;  // px: a few tracing noises, well under the contours' wiggles
  for (const Eigen::Vector2d& pk : p) {
    const Eigen::Vector2d q = pk + scale * t;
    size_t best = 0;
    double best_d2 = 1e300;
    for (size_t k = 0; k < lines.size(); ++k) {
      const double d2 = (q - lines[k].point).squaredNorm();
      if (d2 < best_d2) best_d2 = d2, best = k;
    }
    if (best == 0 || best + 1 == lines.size() || best_d2 > reach * reach * 4) continue;
    const LocalLine& l = lines[best];
    const double d = l.normal.dot(q - l.point);
    if (std::abs(d) > reach) continue;
    const Eigen::Vector2d along(-l.normal.y(), l.normal.x());
    out.push_back({d, l.normal.dot(t), l.tilt_var * std::pow(along.dot(t), 2)});
  }
  return out;
}

}  // namespace

std::optional<ContourFit> contour_scale_least_squares(const std::vector<Eigen::Vector2d>& first,
                                                      const std::vector<Eigen::Vector2d>& second,
                                                      const Eigen::Matrix2d& rot, const Eigen::Vector2d& centre,
                                                      const Eigen::Vector2d& t) {
  const std::vector<LocalLine> lines = local_lines(first);
  if (lines.size() < 3 || t.norm() < 1) return std::nullopt;
  std::vector<Eigen::Vector2d> p;
  for (const auto& s : second) p.push_back(centre + rot * (s - centre));
  // Coarse: the scale whose matched points lie closest, unmatched points costing as much as the
  // farthest match (so a scale cannot win by pushing the contours apart); steps that move the
  // contour by half a pixel.
  const int min_points = 20;
  const double step = 0.5 / t.norm();
  double best_cost = 1e300, scale = 1;
  for (double s = 0.6; s <= 1.4; s += step) {
    const auto m = matches(lines, p, t, s);
    if (int(m.size()) < min_points) continue;
    double cost = double(p.size() - m.size()) * 4.0;
    for (const Match& x : m) cost += x.d * x.d;
    if (cost < best_cost) best_cost = cost, scale = s;
  }
  if (best_cost == 1e300) return std::nullopt;
  // Gauss-Newton on the matched points (the matches re-found at every step).
  std::vector<Match> m;
  for (int it = 0; it < 10; ++it) {
    m = matches(lines, p, t, scale);
    if (int(m.size()) < min_points) return std::nullopt;
    double jj = 0, jd = 0;
    for (const Match& x : m) jj += x.J * x.J, jd += x.J * x.d;
    if (!(jj > 0)) return std::nullopt;
    const double delta = -jd / jj;
    scale += delta;
    if (std::abs(delta) * t.norm() < 1e-4) break;
  }
  m = matches(lines, p, t, scale);
  if (int(m.size()) < min_points) return std::nullopt;
  // The information along the translation, less what the lines' tilt would fake on a contour
  // exactly along it.
  double jj = 0, dd = 0;
  for (const Match& x : m) jj += x.J * x.J - x.J_noise, dd += x.d * x.d;
  ContourFit f;
  f.scale = scale;
  f.points = int(m.size());
  f.residual_px = std::sqrt(dd / double(m.size()));
  f.sigma = jj > 0 ? std::sqrt(dd / double(m.size() - 1) / jj) : 1e300;
  return f;
}

}  // namespace fluoro
