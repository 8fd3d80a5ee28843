#include "engine/random_draws.hpp"
#include "pipelines/registration/start_poses.hpp"

#include <cmath>
#include <numbers>
#include <random>
#include <stdexcept>

namespace fluoro {
namespace {

Eigen::Vector3d random_unit(std::mt19937_64& rng) {
  std::normal_distribution<double> n;
  Eigen::Vector3d v;
  do v = draw3(n, rng);
  while (v.norm() < 1e-6);
  return v.normalized();
}

double mean_distance(const Pose& a, const Pose& b, const std::vector<Eigen::Vector3d>& points) {
  double s = 0;
  for (const auto& p : points) s += (a * p - b * p).norm();
  return s / double(points.size());
}

}  // namespace

Pose start_pose_at_distance(const Pose& truth, const std::vector<Eigen::Vector3d>& surface_ct,
                            const Eigen::Vector3d& centre_ct, double distance_mm, uint64_t seed,
                            const StartPoseParams& params) {
  if (surface_ct.empty()) throw std::invalid_argument("start_pose_at_distance: no surface points");
  if (!(distance_mm > 0)) return truth;
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  double radius = 0;
  for (const auto& p : surface_ct) radius += (p - centre_ct).norm();
  radius = std::max(radius / double(surface_ct.size()), 1.0);
  const Eigen::Vector3d c = truth * centre_ct;
  for (;;) {
    // The share of the distance that comes from rotation, the rotation axis and the direction
    // of translation; the scale s follows by bisection (the distance grows with it).
    const double share = uniform(rng);
    const Eigen::Vector3d axis = random_unit(rng), direction = random_unit(rng);
    const auto at = [&](double s) {
      Pose delta = pose_from_rotation_vector(axis * (share * s / radius), Eigen::Vector3d::Zero());
      delta.translation() = c + direction * ((1 - share) * s) - delta.linear() * c;
      return Pose(delta * truth);
    };
    double lo = 0, hi = distance_mm;
    while (mean_distance(at(hi), truth, surface_ct) < distance_mm && hi < 1e4) hi *= 2;
    for (int i = 0; i < 60 && hi - lo > 1e-6; ++i) {
      const double mid = 0.5 * (lo + hi);
      (mean_distance(at(mid), truth, surface_ct) < distance_mm ? lo : hi) = mid;
    }
    const double s = 0.5 * (lo + hi);
    if (share * s / radius * 180.0 / std::numbers::pi <= params.max_rotation_deg) return at(s);
  }
}

}  // namespace fluoro
