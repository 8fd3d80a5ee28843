#pragma once
// The pose of a known object from 3D-2D pairs with the camera's K known: Levenberg-Marquardt
// (Eigen's) on the reprojection error over the rotation and translation only.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <vector>

namespace fluoro {

// x_cam = R X + t as an isometry (T_camera_object).
using CameraPose = Eigen::Isometry3d;

// The pose minimising the sum of squared pixel distances between `pixels` and K (R X + t) / z,
// from `start`. Needs at least 3 pairs; returns the start unchanged for fewer.
CameraPose refine_pose(const Eigen::Matrix3d& K, const CameraPose& start, const std::vector<Eigen::Vector3d>& points,
                       const std::vector<Eigen::Vector2d>& pixels);

// Pixel of a point under K and a pose (NaN behind the source).
Eigen::Vector2d project_pose(const Eigen::Matrix3d& K, const CameraPose& pose, const Eigen::Vector3d& X);

// RMS pixel distance of the pairs under the pose.
double reprojection_rms(const Eigen::Matrix3d& K, const CameraPose& pose, const std::vector<Eigen::Vector3d>& points,
                        const std::vector<Eigen::Vector2d>& pixels);

}  // namespace fluoro
