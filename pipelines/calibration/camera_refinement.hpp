#pragma once
// Levenberg-Marquardt (Eigen's) on the reprojection error over the intrinsics (fx, fy, cx, cy;
// no skew) and the pose, from a starting camera such as the DLT's.
#include <Eigen/Core>
#include <vector>

#include "engine/camera.hpp"

namespace fluoro {

// The camera minimising the sum of squared pixel distances between `pixels` and the projections
// of `points`. The start's skew is dropped (a digital detector's is zero; the DLT's is noise).
// `iterations` receives the number of function evaluations when not null.
PinholeCamera refine_camera(const PinholeCamera& start, const std::vector<Eigen::Vector3d>& points,
                            const std::vector<Eigen::Vector2d>& pixels, int* evaluations = nullptr);

}  // namespace fluoro
