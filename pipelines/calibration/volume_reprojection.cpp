#include "pipelines/calibration/volume_reprojection.hpp"

#include <algorithm>

namespace fluoro {

ReprojectionGap volume_reprojection_gap(const PinholeCamera& estimate, const PinholeCamera& truth,
                                        const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, int n) {
  return volume_reprojection_gap(estimate, [&](const Eigen::Vector3d& x) { return truth.project(x); }, lo, hi, n);
}

void fiducial_bounds(const PhantomModel& phantom, Eigen::Vector3d* lo, Eigen::Vector3d* hi) {
  *lo = *hi = phantom.fiducials.at(0).position_mm;
  for (const auto& f : phantom.fiducials) *lo = lo->cwiseMin(f.position_mm), *hi = hi->cwiseMax(f.position_mm);
}

ReprojectionGap volume_reprojection_gap(const PinholeCamera& estimate,
                                        const std::function<Eigen::Vector2d(const Eigen::Vector3d&)>& truth,
                                        const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, int n) {
  ReprojectionGap g;
  int count = 0;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j)
      for (int k = 0; k < n; ++k) {
        const Eigen::Vector3d s = Eigen::Vector3d(i, j, k) / std::max(1, n - 1);
        const Eigen::Vector3d x = lo + s.cwiseProduct(hi - lo);
        const double d = (estimate.project(x) - truth(x)).norm();
        g.mean_px += d;
        g.max_px = std::max(g.max_px, d);
        ++count;
      }
  g.mean_px /= count;
  return g;
}

}  // namespace fluoro
