#include "pipelines/distal_locking/pose_refinement.hpp"

#include <cmath>
#include <limits>
#include <unsupported/Eigen/LevenbergMarquardt>

#include "engine/pose.hpp"

namespace fluoro {
namespace {

// Residuals of the pairs; parameters: a rotation vector applied on the left of the start's R (near
// zero, far from its singularity) and the translation.
struct Reprojection : Eigen::DenseFunctor<double> {
  const Eigen::Matrix3d& K;
  const Eigen::Matrix3d R0;
  const std::vector<Eigen::Vector3d>& X;
  const std::vector<Eigen::Vector2d>& x;
  Reprojection(const Eigen::Matrix3d& k, const Eigen::Matrix3d& r0, const std::vector<Eigen::Vector3d>& X_,
               const std::vector<Eigen::Vector2d>& x_)
      : DenseFunctor<double>(6, 2 * int(X_.size())), K(k), R0(r0), X(X_), x(x_) {}

  int operator()(const InputType& p, ValueType& f) const {
    const Eigen::Matrix3d R = rotation_from_vector(p.head<3>()) * R0;
    for (size_t i = 0; i < X.size(); ++i) {
      const Eigen::Vector3d q = K * (R * X[i] + p.tail<3>());
      f(2 * Eigen::Index(i)) = q.x() / q.z() - x[i].x();
      f(2 * Eigen::Index(i) + 1) = q.y() / q.z() - x[i].y();
    }
    return 0;
  }
  int df(const InputType& p, JacobianType& J) const {
    const Eigen::Matrix3d R = rotation_from_vector(p.head<3>()) * R0;
    for (size_t i = 0; i < X.size(); ++i) {
      const Eigen::Vector3d rx = R * X[i], c = rx + p.tail<3>(), q = K * c;
      // d(q.xy / q.z) / dc = [K row0 - u K row2; K row1 - v K row2] / q.z
      Eigen::Matrix<double, 2, 3> dc;
      dc.row(0) = (K.row(0) - q.x() / q.z() * K.row(2)) / q.z();
      dc.row(1) = (K.row(1) - q.y() / q.z() * K.row(2)) / q.z();
      Eigen::Matrix3d skew;
      skew << 0, -rx.z(), rx.y(), rx.z(), 0, -rx.x(), -rx.y(), rx.x(), 0;
      J.block<2, 3>(2 * Eigen::Index(i), 0) = -dc * skew;
      J.block<2, 3>(2 * Eigen::Index(i), 3) = dc;
    }
    return 0;
  }
};

}  // namespace

Eigen::Vector2d project_pose(const Eigen::Matrix3d& K, const CameraPose& pose, const Eigen::Vector3d& X) {
  const Eigen::Vector3d q = K * (pose * X);
  if (!(q.z() > 0)) return Eigen::Vector2d::Constant(std::numeric_limits<double>::quiet_NaN());
  return q.head<2>() / q.z();
}

double reprojection_rms(const Eigen::Matrix3d& K, const CameraPose& pose, const std::vector<Eigen::Vector3d>& points,
                        const std::vector<Eigen::Vector2d>& pixels) {
  if (points.empty()) return 0;
  double ss = 0;
  for (size_t i = 0; i < points.size(); ++i) ss += (project_pose(K, pose, points[i]) - pixels[i]).squaredNorm();
  return std::sqrt(ss / double(points.size()));
}

CameraPose refine_pose(const Eigen::Matrix3d& K, const CameraPose& start, const std::vector<Eigen::Vector3d>& points,
                       const std::vector<Eigen::Vector2d>& pixels) {
  if (points.size() < 3) return start;
  CameraPose pose = start;
  // Two rounds: the second restarts the rotation vector at zero, where the Jacobian is exact.
  for (int round = 0; round < 2; ++round) {
    Reprojection f(K, pose.linear(), points, pixels);
    Eigen::LevenbergMarquardt<Reprojection> lm(f);
    lm.setXtol(1e-12);
    lm.setFtol(1e-14);
    lm.setMaxfev(200);
    Eigen::VectorXd p(6);
    p << 0, 0, 0, pose.translation();
    lm.minimize(p);
    const Eigen::Matrix3d R = rotation_from_vector(p.head<3>()) * pose.linear();
    pose.linear() = R;
    pose.translation() = p.tail<3>();
  }
  return pose;
}

}  // namespace fluoro
