#pragma once
// A 3D point from its pixel positions on two or more calibrated X-rays: the point closest (in
// the least-squares sense) to the rays from each source through the pixels.
#include <Eigen/Core>
#include <string>
#include <vector>

#include "engine/camera.hpp"

namespace fluoro {

struct Triangulation {
  Eigen::Vector3d point;
  double rms_ray_distance_mm = 0;  // how far the rays pass from the point (a consistency check)
};

// Throws InputError naming `what` for fewer than two views, mismatched sizes, a non-finite pixel,
// or rays too close to parallel to intersect (under about 1 degree apart).
Triangulation triangulate(const std::vector<PinholeCamera>& cameras, const std::vector<Eigen::Vector2d>& pixels,
                          const std::string& what);

}  // namespace fluoro
