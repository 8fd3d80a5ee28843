#include "engine/camera.hpp"

#include <Eigen/Dense>
#include <cmath>
#include <limits>

#include "engine/error.hpp"

namespace fluoro {

Eigen::Vector2d PinholeCamera::project(const Eigen::Vector3d& x_world) const {
  const Eigen::Vector3d xc = R * x_world + t;
  if (!(xc.z() > 0)) return Eigen::Vector2d::Constant(std::numeric_limits<double>::quiet_NaN());
  const Eigen::Vector3d p = K * (xc / xc.z());
  return p.head<2>();
}

Eigen::Vector3d PinholeCamera::ray_direction(double u, double v) const {
  return (R.transpose() * K.inverse() * Eigen::Vector3d(u, v, 1)).normalized();
}

Eigen::Matrix<double, 3, 4> PinholeCamera::projection_matrix() const {
  Eigen::Matrix<double, 3, 4> rt;
  rt << R, t;
  return K * rt;
}

PinholeCamera PinholeCamera::look_at(const Eigen::Vector3d& source, const Eigen::Vector3d& target,
                                     const Eigen::Vector3d& down, double focal_px, int width,
                                     int height) {
  PinholeCamera c;
  c.width = width;
  c.height = height;
  const Eigen::Vector3d z = (target - source).normalized();
  const Eigen::Vector3d x = down.cross(z).normalized();  // image columns grow along x
  const Eigen::Vector3d y = z.cross(x);                  // image rows grow along y ("down")
  c.R.row(0) = x.transpose();
  c.R.row(1) = y.transpose();
  c.R.row(2) = z.transpose();
  c.t = -c.R * source;
  c.K << focal_px, 0, (width - 1) * 0.5, 0, focal_px, (height - 1) * 0.5, 0, 0, 1;
  return c;
}

void validate_camera(const PinholeCamera& c, const std::string& what) {
  if (c.width <= 0 || c.height <= 0)
    throw_input_error(what, "image size " + std::to_string(c.width) + "x" +
                                std::to_string(c.height) + " is not positive");
  // 2^28 pixels (16384^2) is beyond any detector; a larger size is a typo, not an image to allocate.
  if (double(c.width) * double(c.height) > double(1 << 28))
    throw_input_error(what, "image size " + std::to_string(c.width) + "x" + std::to_string(c.height) +
                                " is too large (more than 2^28 pixels)");
  if (!c.K.allFinite() || !c.R.allFinite() || !c.t.allFinite())
    throw_input_error(what, "camera has non-finite entries");
  if (std::abs(c.K(2, 0)) > 1e-12 || std::abs(c.K(2, 1)) > 1e-12 || std::abs(c.K(2, 2) - 1) > 1e-12)
    throw_input_error(what, "K's last row must be 0 0 1");
  if (std::abs(c.K(1, 0)) > 1e-12) throw_input_error(what, "K must be upper triangular");
  if (!(std::abs(c.K(0, 0)) > 1e-9) || !(std::abs(c.K(1, 1)) > 1e-9))
    throw_input_error(what, "K is singular (zero focal length)");
  if (!(c.R.transpose() * c.R).isApprox(Eigen::Matrix3d::Identity(), 1e-6))
    throw_input_error(what, "R is not orthonormal");
  if (c.R.determinant() < 0) throw_input_error(what, "R is improper (det = -1, a reflection)");
  if (c.pixel_spacing_mm && !((c.pixel_spacing_mm->array() > 0).all() && c.pixel_spacing_mm->allFinite()))
    throw_input_error(what, "pixel_spacing_mm must be two positive numbers");
}

PinholeCamera camera_from_projection(const Eigen::Matrix<double, 3, 4>& P, int width, int height,
                                     const std::string& what) {
  if (!P.allFinite()) throw_input_error(what, "P has non-finite entries");
  Eigen::Matrix3d M = P.leftCols<3>();
  if (std::abs(M.determinant()) < 1e-12 * std::pow(M.norm(), 3))
    throw_input_error(what, "P's left 3x3 block is singular");
  // RQ decomposition of M via QR of the row-reversed transpose.
  Eigen::Matrix3d flip = Eigen::Matrix3d::Zero();
  flip(0, 2) = flip(1, 1) = flip(2, 0) = 1;
  Eigen::HouseholderQR<Eigen::Matrix3d> qr((flip * M).transpose());
  Eigen::Matrix3d q = qr.householderQ();
  Eigen::Matrix3d r = qr.matrixQR().triangularView<Eigen::Upper>();
  Eigen::Matrix3d K = flip * r.transpose() * flip;
  Eigen::Matrix3d R = flip * q.transpose();
  // Make K's diagonal positive.
  Eigen::Matrix3d s = Eigen::Matrix3d::Identity();
  for (int i = 0; i < 3; ++i)
    if (K(i, i) < 0) s(i, i) = -1;
  K = K * s;
  R = s * R;
  // P = lambda K [R | t]: K^-1 of the unnormalised K removes lambda from t as well.
  Eigen::Vector3d t = K.inverse() * P.col(3);
  K /= K(2, 2);
  if (R.determinant() < 0) {  // P given with an overall negative scale
    R = -R;
    t = -t;
  }
  PinholeCamera c;
  c.width = width;
  c.height = height;
  c.K = K;
  c.R = R;
  c.t = t;
  validate_camera(c, what);
  return c;
}

}  // namespace fluoro
