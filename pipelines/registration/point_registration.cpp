#include "pipelines/registration/point_registration.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <cmath>

#include "engine/error.hpp"

namespace fluoro {

PointRegistration register_points(const std::vector<Eigen::Vector3d>& from, const std::vector<Eigen::Vector3d>& to,
                                  const std::vector<double>& weights, const std::string& what) {
  const size_t n = from.size();
  if (to.size() != n) throw_input_error(what, std::to_string(n) + " points paired with " + std::to_string(to.size()));
  if (!weights.empty() && weights.size() != n)
    throw_input_error(what, std::to_string(weights.size()) + " weights for " + std::to_string(n) + " points");
  if (n < 3) throw_input_error(what, "rigid registration needs at least 3 point pairs, got " + std::to_string(n));
  double total = 0;
  Eigen::Vector3d cf = Eigen::Vector3d::Zero(), ct = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < n; ++i) {
    const double w = weights.empty() ? 1.0 : weights[i];
    if (!std::isfinite(w) || w < 0) throw_input_error(what, "weight " + std::to_string(i) + " is negative or not finite");
    if (!from[i].allFinite() || !to[i].allFinite()) throw_input_error(what, "point " + std::to_string(i) + " is not finite");
    total += w;
    cf += w * from[i];
    ct += w * to[i];
  }
  if (!(total > 0)) throw_input_error(what, "all weights are zero");
  cf /= total;
  ct /= total;

  // Weighted cross-covariance, and Horn's symmetric 4x4 matrix whose top eigenvector is the
  // rotation quaternion (w, x, y, z).
  Eigen::Matrix3d S = Eigen::Matrix3d::Zero();
  Eigen::Matrix3d spread = Eigen::Matrix3d::Zero();
  for (size_t i = 0; i < n; ++i) {
    const double w = weights.empty() ? 1.0 : weights[i];
    const Eigen::Vector3d a = from[i] - cf, b = to[i] - ct;
    S += w * a * b.transpose();
    spread += w * a * a.transpose();
  }
  // Collinear (or coincident) points: the second largest principal spread vanishes.
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> principal(spread);
  if (principal.eigenvalues()(1) <= 1e-12 * std::max(1.0, principal.eigenvalues()(2)))
    throw_input_error(what, "points are collinear: the rotation about their line is undetermined");
  Eigen::Matrix4d N;
  N << S(0, 0) + S(1, 1) + S(2, 2), S(1, 2) - S(2, 1), S(2, 0) - S(0, 2), S(0, 1) - S(1, 0),
      S(1, 2) - S(2, 1), S(0, 0) - S(1, 1) - S(2, 2), S(0, 1) + S(1, 0), S(2, 0) + S(0, 2),
      S(2, 0) - S(0, 2), S(0, 1) + S(1, 0), -S(0, 0) + S(1, 1) - S(2, 2), S(1, 2) + S(2, 1),
      S(0, 1) - S(1, 0), S(2, 0) + S(0, 2), S(1, 2) + S(2, 1), -S(0, 0) - S(1, 1) + S(2, 2);
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix4d> eig(N);
  const Eigen::Vector4d q = eig.eigenvectors().col(3);  // eigenvalues ascend
  const Eigen::Quaterniond rotation(q(0), q(1), q(2), q(3));

  PointRegistration r;
  r.transform = Pose::Identity();
  r.transform.linear() = rotation.normalized().toRotationMatrix();
  r.transform.translation() = ct - r.transform.linear() * cf;
  double sum = 0;
  for (size_t i = 0; i < n; ++i) {
    const double w = weights.empty() ? 1.0 : weights[i];
    const double e = (r.transform * from[i] - to[i]).norm();
    sum += w * e * e;
    r.max_mm = std::max(r.max_mm, e);
  }
  r.rms_mm = std::sqrt(sum / total);
  return r;
}

}  // namespace fluoro
