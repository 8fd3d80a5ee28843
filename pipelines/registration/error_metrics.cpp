#include "pipelines/registration/error_metrics.hpp"

#include <cmath>
#include <limits>

namespace fluoro {

RegistrationErrors registration_errors(const Pose& estimate, const Pose& truth,
                                       const std::vector<Eigen::Vector3d>& surface,
                                       const std::vector<Eigen::Vector3d>& fiducials,
                                       const std::vector<PinholeCamera>& views) {
  constexpr double nan = std::numeric_limits<double>::quiet_NaN();
  RegistrationErrors e;
  const Pose error = estimate * truth.inverse();
  e.rotation_deg = rotation_angle_deg(error);
  e.translation_mm = error.translation().norm();
  double sum = 0;
  for (const auto& p : surface) {
    const double d = (estimate * p - truth * p).norm();
    sum += d;
    e.surface_tre_max_mm = std::max(e.surface_tre_max_mm, d);
  }
  e.surface_tre_mean_mm = surface.empty() ? nan : sum / double(surface.size());
  if (surface.empty()) e.surface_tre_max_mm = nan;
  sum = 0;
  for (const auto& f : fiducials) sum += (estimate * f - truth * f).norm();
  e.fiducial_tre_mean_mm = fiducials.empty() ? nan : sum / double(fiducials.size());
  sum = 0;
  size_t count = 0;
  bool spacing = !views.empty();
  for (const auto& v : views) spacing = spacing && v.pixel_spacing_mm.has_value();
  if (spacing && !surface.empty()) {
    for (const auto& v : views)
      for (const auto& p : surface) {
        const Eigen::Vector2d d = v.project(estimate * p) - v.project(truth * p);
        if (!d.allFinite()) continue;  // behind a source
        sum += d.cwiseProduct(*v.pixel_spacing_mm).norm();
        ++count;
      }
  }
  e.mpd_mm = count ? sum / double(count) : nan;
  return e;
}

std::vector<Eigen::Vector3d> surface_points(const Volume& hu, double iso_hu, size_t max_points) {
  const auto& g = hu.geometry;
  std::vector<Eigen::Vector3d> all;
  auto below = [&](int i, int j, int k) {
    if (i < 0 || j < 0 || k < 0 || i >= g.size.x() || j >= g.size.y() || k >= g.size.z()) return true;
    return double(hu.at(i, j, k)) < iso_hu;
  };
  for (int k = 0; k < g.size.z(); ++k)
    for (int j = 0; j < g.size.y(); ++j)
      for (int i = 0; i < g.size.x(); ++i)
        if (!below(i, j, k) && (below(i - 1, j, k) || below(i + 1, j, k) || below(i, j - 1, k) ||
                                below(i, j + 1, k) || below(i, j, k - 1) || below(i, j, k + 1)))
          all.push_back(g.index_to_physical(Eigen::Vector3d(i, j, k)));
  if (max_points == 0 || all.size() <= max_points) return all;
  std::vector<Eigen::Vector3d> subset;
  const double stride = double(all.size()) / double(max_points);
  for (size_t i = 0; i < max_points; ++i) subset.push_back(all[size_t(double(i) * stride)]);
  return subset;
}

Eigen::Vector3d mean_point(const std::vector<Eigen::Vector3d>& points) {
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (const auto& p : points) c += p;
  return points.empty() ? c : Eigen::Vector3d(c / double(points.size()));
}

}  // namespace fluoro
