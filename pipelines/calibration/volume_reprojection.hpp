#pragma once
// The calibration goal's metric: project points spread through a volume with an estimated and a
// true camera and compare the pixels (not only the fiducials, which the fit saw).
#include <Eigen/Core>
#include <functional>

#include "engine/camera.hpp"
#include "engine/phantom_model.hpp"

namespace fluoro {

// Mean and largest pixel distance over the sampled points.
struct ReprojectionGap {
  double mean_px = 0;
  double max_px = 0;
};

// Samples an n x n x n grid spanning the box [lo, hi] (world frame of both cameras).
ReprojectionGap volume_reprojection_gap(const PinholeCamera& estimate, const PinholeCamera& truth,
                                        const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, int n = 10);
// The same against a true projection that is not a pinhole (a distorted image's, say).
ReprojectionGap volume_reprojection_gap(const PinholeCamera& estimate,
                                        const std::function<Eigen::Vector2d(const Eigen::Vector3d&)>& truth,
                                        const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, int n = 10);

// The axis-aligned box of the phantom's fiducials: where the goal's points are sampled.
void fiducial_bounds(const PhantomModel& phantom, Eigen::Vector3d* lo, Eigen::Vector3d* hi);

}  // namespace fluoro
