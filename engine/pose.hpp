#pragma once
// Rigid transforms. A CT pose is T_world_ct: CT-frame points to world points.
#include <Eigen/Geometry>
#include <numbers>
#include <string>

namespace fluoro {

using Pose = Eigen::Isometry3d;

// Degrees to radians.
constexpr double radians(double degrees) { return degrees * std::numbers::pi / 180.0; }

// The rotation matrix of a rotation vector (axis * angle, radians); the identity for zero, NaN for a
// NaN vector (a diverged solver step stays visible; pose_from_rotation_vector takes it as zero).
Eigen::Matrix3d rotation_from_vector(const Eigen::Vector3d& rotation);

// Rotation from a rotation vector (axis * angle, radians) and a translation in mm.
Pose pose_from_rotation_vector(const Eigen::Vector3d& rotation, const Eigen::Vector3d& translation);

// Throws InputError naming `what` if m is not a finite proper rigid transform
// (R^T R = I and det R = +1 within 1e-6, last row 0 0 0 1).
Pose pose_from_matrix(const Eigen::Matrix4d& m, const std::string& what);

// Rotation angle (degrees) and translation length (mm) of a transform, for error reports.
double rotation_angle_deg(const Pose& p);

// Angle (degrees, 0-90) between two lines with these directions: an axis has no sign.
double axis_angle_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b);

}  // namespace fluoro
