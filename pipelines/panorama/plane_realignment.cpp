#include "pipelines/panorama/plane_realignment.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

#include "engine/median.hpp"

namespace fluoro {

std::optional<std::pair<double, double>> contour_plane_scale(const std::vector<Eigen::Vector2d>& first,
                                                             const std::vector<Eigen::Vector2d>& second,
                                                             const Eigen::Matrix2d& rot, const Eigen::Vector2d& centre,
                                                             const Eigen::Vector2d& t) {
  const double len = t.norm();
  if (len < 1 || first.size() < 2) return std::nullopt;
  const Eigen::Vector2d dir = t / len;
  std::vector<double> scales;
  for (size_t k = 0; k < second.size(); ++k) {
    const Eigen::Vector2d p = centre + rot * (second[k] - centre);
    // The contour's local direction: a crossing must be with the same stretch of outline (a ray
    // along the translation can also meet the other flank of a bump or the bone's rounded end).
    const Eigen::Vector2d along =
        (rot * (second[std::min(k + 3, second.size() - 1)] - second[k > 2 ? k - 3 : 0])).normalized();
    // Crossings of the ray p + mu dir with the first contour; the one nearest mu = |t| (scale 1).
    double best = std::nan("");
    for (size_t k = 0; k + 1 < first.size(); ++k) {
      const Eigen::Vector2d a = first[k], b = first[k + 1], seg = b - a;
      const double den = dir.x() * seg.y() - dir.y() * seg.x();
      if (std::abs(den) < 1e-12) continue;
      // A stretch nearly along the translation says nothing about the scale along it; the
      // stretch's direction over a few points, since a traced point's jitter tilts single segments.
      const Eigen::Vector2d local = (first[std::min(k + 4, first.size() - 1)] - first[k > 2 ? k - 3 : 0]).normalized();
      if (std::abs(dir.x() * local.y() - dir.y() * local.x()) < std::sin(10.0 * M_PI / 180)) continue;
      const Eigen::Vector2d w = a - p;
      const double mu = (w.x() * seg.y() - w.y() * seg.x()) / den;
      const double nu = (w.x() * dir.y() - w.y() * dir.x()) / den;
      if (nu < 0 || nu > 1) continue;
      if (std::abs(along.dot(local)) < std::cos(30.0 * M_PI / 180)) continue;
      const double scale = mu / len;
      if (scale < 0.6 || scale > 1.4) continue;
      if (std::isnan(best) || std::abs(scale - 1) < std::abs(best - 1)) best = scale;
    }
    if (!std::isnan(best)) scales.push_back(best);
  }
  if (scales.size() < 5) return std::nullopt;
  // The seed takes the mean of the per-point scales; outliers (a trace slipping to another edge)
  // are dropped first by their distance from the median.
  const double m = upper_median(scales);
  std::vector<double> dev;
  for (double s : scales) dev.push_back(std::abs(s - m));
  const double mad = std::max(1e-4, 1.4826 * upper_median(dev));
  double sum = 0, sum2 = 0;
  int n = 0;
  for (double s : scales)
    if (std::abs(s - m) <= 3 * mad) sum += s, sum2 += s * s, ++n;
  const double mean = sum / n, var = std::max(0.0, sum2 / n - mean * mean);
  return std::make_pair(mean, std::sqrt(var / n));
}

}  // namespace fluoro
