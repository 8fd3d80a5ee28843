#include "pipelines/distal_locking/guide_pairing_check.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace fluoro {

std::vector<int> pair_nearest(const std::vector<Eigen::Vector2d>& projected, const std::vector<Eigen::Vector2d>& det,
                              double tol, int* count) {
  struct C {
    double d;
    int m, k;
  };
  std::vector<C> c;
  for (int m = 0; m < int(projected.size()); ++m) {
    if (!projected[size_t(m)].allFinite()) continue;
    for (int k = 0; k < int(det.size()); ++k) {
      const double d = (projected[size_t(m)] - det[size_t(k)]).norm();
      if (d < tol) c.push_back({d, m, k});
    }
  }
  std::sort(c.begin(), c.end(), [](const C& a, const C& b) { return a.d < b.d; });
  std::vector<int> of(projected.size(), -1);
  std::vector<bool> used(det.size(), false);
  *count = 0;
  for (const auto& x : c)
    if (of[size_t(x.m)] < 0 && !used[size_t(x.k)]) of[size_t(x.m)] = x.k, used[size_t(x.k)] = true, ++*count;
  return of;
}

CameraPose refit_without_outliers(const Eigen::Matrix3d& K, const CameraPose& pose, const std::vector<Eigen::Vector3d>& model,
                                  const std::vector<Eigen::Vector2d>& det, const std::vector<int>& of, int min_pairs,
                                  int* outliers) {
  *outliers = 0;
  std::vector<double> res;
  for (size_t i = 0; i < model.size(); ++i)
    if (of[i] >= 0) res.push_back((project_pose(K, pose, model[i]) - det[size_t(of[i])]).norm());
  if (res.empty()) return pose;
  std::vector<double> sorted = res;
  std::nth_element(sorted.begin(), sorted.begin() + long(sorted.size() / 2), sorted.end());
  const double cut = std::max(0.25, 3.0 * 1.4826 * sorted[sorted.size() / 2]);
  std::vector<Eigen::Vector3d> X;
  std::vector<Eigen::Vector2d> x;
  for (size_t i = 0, k = 0; i < model.size(); ++i)
    if (of[i] >= 0 && res[k++] < cut) X.push_back(model[i]), x.push_back(det[size_t(of[i])]);
  *outliers = int(res.size() - X.size());
  return int(X.size()) >= min_pairs ? refine_pose(K, pose, X, x) : pose;
}

CheckedPairing check_guide_pairing(const Eigen::Matrix3d& K, const std::vector<Eigen::Vector3d>& model,
                                   const std::vector<Eigen::Vector2d>& det, const CameraPose& start, double tight_px,
                                   int min_pairs, const Eigen::Vector2i& image_size, double sphere_radius_mm) {
  CheckedPairing out;
  out.pose = start;
  std::vector<Eigen::Vector2d> projected(model.size());
  const auto project = [&] {
    for (size_t i = 0; i < model.size(); ++i) projected[i] = project_pose(K, out.pose, model[i]);
  };
  int inliers = 0;
  for (int round = 0; round < 4; ++round) {
    project();
    int count = 0;
    const std::vector<int> of = pair_nearest(projected, det, tight_px, &count);
    const bool same = of == out.detection_of;
    out.detection_of = of;
    out.pairs = count;
    if (same || count < 3) break;
    out.pose = refit_without_outliers(K, out.pose, model, det, of, min_pairs, &out.outliers);
    inliers = count - out.outliers;
  }
  // Blobs of two spheres: the detector finds one dark circle where two spheres, one on each plane,
  // lie nearly on one ray; its centroid is neither's projection and which sphere it is paired with
  // is a coin toss (the big sweep: 6 of 264 images, the other sphere 0.04-0.2 px nearer), so it is
  // left unpaired, as the issue asks of ambiguous pairings, and the pose refitted without it.
  project();
  const double f = 0.5 * (K(0, 0) + K(1, 1));
  bool unpaired = false;
  for (size_t i = 0; i < model.size(); ++i) {
    if (out.detection_of[i] < 0) continue;
    const Eigen::Vector2d& d = det[size_t(out.detection_of[i])];
    for (size_t j = 0; j < model.size(); ++j) {
      if (j == i || out.detection_of[j] >= 0 || !projected[j].allFinite()) continue;
      // The blob's centroid lies between the two projections (about halfway for two equal
      // spheres); a detection at sphere i's own projection with a hidden sphere j near it is i's.
      const double radius = f * sphere_radius_mm / (out.pose * model[j]).z();
      if ((projected[j] - d).norm() < radius && (projected[i] - d).norm() > 0.25 * (projected[i] - projected[j]).norm()) {
        out.detection_of[i] = -1, --out.pairs, ++out.blobs, unpaired = true;
        break;
      }
    }
  }
  if (unpaired) {
    out.pose = refit_without_outliers(K, out.pose, model, det, out.detection_of, min_pairs, &out.outliers);
    inliers = out.pairs - out.outliers;
    project();
  }
  double ss = 0;
  out.in_image = 0;
  for (size_t i = 0; i < model.size(); ++i) {
    const Eigen::Vector2d& p = projected[i];
    const bool inside = p.allFinite() && (image_size.x() <= 0 || (p.x() >= 0 && p.y() >= 0 && p.x() <= image_size.x() - 1 &&
                                                                  p.y() <= image_size.y() - 1));
    out.in_image += inside;
    if (out.detection_of[i] >= 0) ss += (p - det[size_t(out.detection_of[i])]).squaredNorm();
  }
  out.rms_px = out.pairs ? std::sqrt(ss / out.pairs) : 0;
  char reason[240];
  if (inliers < min_pairs) {
    std::snprintf(reason, sizeof reason, "too few spheres matched: %d pairs agree with the guide's pose (%d needed)", inliers,
                  min_pairs);
    out.failure_reason = reason;
    return out;
  }
  if (double(out.pairs) < kMinExplainedFraction * out.in_image) {
    std::snprintf(reason, sizeof reason,
                  "too few spheres matched: the guide's pose explains %d of the %d spheres it puts in the image (at least half "
                  "needed: a pose from a few coincidental pairs, not a hidden guide)",
                  out.pairs, out.in_image);
    out.failure_reason = reason;
    return out;
  }
  out.ok = true;
  return out;
}

}  // namespace fluoro
