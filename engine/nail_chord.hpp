#pragma once
// The length of metal a ray crosses in an intramedullary nail: a solid cylinder (NAIL.json's
// diameter, along the nail's x) minus its cylindrical locking holes (along the nail's z). Exact,
// from ray-cylinder intervals: the hole's visible lens shrinks as the view tilts, as in an X-ray.
#include <Eigen/Core>
#include <vector>

#include "engine/distal_locking_models.hpp"
#include "engine/ray_cylinder.hpp"

namespace fluoro {

// A nail placed in the camera frame (x_cam = R x_nail + t), as cylinders ready for ray queries.
struct PlacedNail {
  Cylinder rod;
  std::vector<Cylinder> holes;
};

// `x_min`, `x_max`: the rod's extent along its axis in the nail's frame (infinite by default).
inline PlacedNail place_nail(const NailModel& nail, const Eigen::Matrix3d& R, const Eigen::Vector3d& t,
                             double x_min = -HUGE_VAL, double x_max = HUGE_VAL) {
  PlacedNail p;
  p.rod = {t, R.col(0), 0.5 * nail.diameter_mm, x_min, x_max};
  for (const auto& h : nail.holes) p.holes.push_back({R * h.center_mm + t, R.col(2), 0.5 * h.diameter_mm});
  return p;
}

// Metal chord (mm) along the unit ray direction d from the source (camera origin).
inline double nail_chord_mm(const PlacedNail& n, const Eigen::Vector3d& d) {
  const RayInterval rod = ray_in_cylinder(n.rod, d);
  if (rod.length() <= 0) return 0.0;
  double len = rod.length();
  for (const auto& h : n.holes) len -= rod.intersect(ray_in_cylinder(h, d)).length();
  return len;
}

}  // namespace fluoro
