#include "engine/pose.hpp"

#include <cmath>
#include <numbers>

#include "engine/error.hpp"

namespace fluoro {

Eigen::Matrix3d rotation_from_vector(const Eigen::Vector3d& rotation) {
  const double angle = rotation.norm();
  return angle == 0 ? Eigen::Matrix3d::Identity() : Eigen::AngleAxisd(angle, rotation / angle).toRotationMatrix();
}

Pose pose_from_rotation_vector(const Eigen::Vector3d& rotation, const Eigen::Vector3d& translation) {
  Pose p = Pose::Identity();
  const double angle = rotation.norm();
  if (angle > 0) p.linear() = Eigen::AngleAxisd(angle, rotation / angle).toRotationMatrix();
  p.translation() = translation;
  return p;
}

Pose pose_from_matrix(const Eigen::Matrix4d& m, const std::string& what) {
  if (!m.allFinite()) throw_input_error(what, "transform has non-finite entries");
  if (!m.row(3).isApprox(Eigen::RowVector4d(0, 0, 0, 1), 1e-9) || std::abs(m(3, 3) - 1) > 1e-9)
    throw_input_error(what, "transform's last row is not 0 0 0 1");
  const Eigen::Matrix3d r = m.topLeftCorner<3, 3>();
  if (!(r.transpose() * r).isApprox(Eigen::Matrix3d::Identity(), 1e-6))
    throw_input_error(what, "rotation part is not orthonormal");
  if (r.determinant() < 0) throw_input_error(what, "rotation part is improper (det = -1, a reflection)");
  Pose p = Pose::Identity();
  p.matrix() = m;
  return p;
}

double rotation_angle_deg(const Pose& p) {
  return Eigen::AngleAxisd(p.rotation()).angle() * 180.0 / std::numbers::pi;
}

double axis_angle_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::acos(std::min(1.0, std::abs(a.normalized().dot(b.normalized())))) * 180.0 / std::numbers::pi;
}

}  // namespace fluoro
