#pragma once
// Pinhole camera in the OpenCV convention: x_cam = R x_world + t, (u, v) = K x_cam / z,
// pixel (0, 0) the centre of the top-left pixel. The X-ray source is C = -R^T t.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <optional>
#include <string>

namespace fluoro {

struct PinholeCamera {
  int width = 0;
  int height = 0;
  Eigen::Matrix3d K = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
  std::optional<Eigen::Vector2d> pixel_spacing_mm;  // detector pixel size, for reports only

  Eigen::Vector3d source() const { return -R.transpose() * t; }
  // [R | t] as a rigid transform: world points to camera-frame points.
  Eigen::Isometry3d camera_from_world() const {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = R;
    T.translation() = t;
    return T;
  }
  // Pixel coordinates of a world point; z <= 0 (behind the source) gives NaN.
  Eigen::Vector2d project(const Eigen::Vector3d& x_world) const;
  // Unit world direction of the ray from the source through pixel (u, v).
  Eigen::Vector3d ray_direction(double u, double v) const;
  Eigen::Matrix<double, 3, 4> projection_matrix() const;

  // A camera looking from `source` at `target`, with focal length f (pixels), principal point at
  // the image centre, and the image's row direction close to `down` (world).
  static PinholeCamera look_at(const Eigen::Vector3d& source, const Eigen::Vector3d& target,
                               const Eigen::Vector3d& down, double focal_px, int width, int height);
};

// Throws InputError naming `what` for a non-positive size, a non-finite or singular K
// (or K[2] != (0, 0, 1)), an improper or non-orthonormal R, or a non-finite t.
void validate_camera(const PinholeCamera& c, const std::string& what);

// Decomposes P = K [R | t] (3x4, any scale) with K's diagonal positive. Throws InputError on a
// rank-deficient P.
PinholeCamera camera_from_projection(const Eigen::Matrix<double, 3, 4>& P, int width, int height,
                                     const std::string& what);

}  // namespace fluoro
