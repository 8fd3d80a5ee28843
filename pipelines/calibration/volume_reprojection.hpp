#pragma once
// The calibration goal's metric: project points spread through a volume with an estimated and a
// true camera and compare the pixels (not only the fiducials, which the fit saw).
#include <Eigen/Core>

#include "engine/camera.hpp"

namespace fluoro {

// Mean and largest pixel distance over the sampled points.
struct ReprojectionGap {
  double mean_px = 0;
  double max_px = 0;
};

// Samples an n x n x n grid spanning the box [lo, hi] (world frame of both cameras).
ReprojectionGap volume_reprojection_gap(const PinholeCamera& estimate, const PinholeCamera& truth,
                                        const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, int n = 10);

}  // namespace fluoro
