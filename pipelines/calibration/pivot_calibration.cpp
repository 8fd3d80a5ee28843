#include "pipelines/calibration/pivot_calibration.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <numbers>

namespace fluoro {

PivotCalibration pivot_calibration(const std::vector<Pose>& tracker_from_tool, const PivotParams& params) {
  PivotCalibration r;
  const size_t n = tracker_from_tool.size();
  r.poses = n;
  if (n < std::max<size_t>(params.min_poses, 3)) {
    r.failure_reason = "too few poses: " + std::to_string(n) + " given, at least " +
                       std::to_string(std::max<size_t>(params.min_poses, 3)) + " pivoting about two or more axes are needed";
    return r;
  }
  // R_i tip - pivot = -p_i for every pose: A x = b with x = (tip, pivot), A's rows [R_i, -I].
  // Solved through the 6x6 normal equations, accumulated directly: the smallest singular value of A
  // (the rotation spread below) squared stays far above double precision for any pose set the
  // spread test accepts, and fixed-size 6x6 solvers compile in a fraction of a dynamic SVD's time
  // (minutes under the sanitizers).
  using Matrix6d = Eigen::Matrix<double, 6, 6>;
  using Vector6d = Eigen::Matrix<double, 6, 1>;
  Matrix6d normal = Matrix6d::Zero();
  Vector6d rhs = Vector6d::Zero();
  for (const Pose& T : tracker_from_tool) {
    const Eigen::Matrix3d R = T.linear();
    const Eigen::Vector3d p = T.translation();
    normal.topLeftCorner<3, 3>() += R.transpose() * R;
    normal.topRightCorner<3, 3>() -= R.transpose();
    normal.bottomLeftCorner<3, 3>() -= R;
    normal.bottomRightCorner<3, 3>() += Eigen::Matrix3d::Identity();
    rhs.head<3>() -= R.transpose() * p;
    rhs.tail<3>() += p;
  }
  const Eigen::SelfAdjointEigenSolver<Matrix6d> eigen(normal);
  const double sigma_min = std::sqrt(std::max(0.0, eigen.eigenvalues()(0)));
  r.rotation_spread_deg = 2 * std::asin(std::min(1.0, sigma_min / std::sqrt(double(n)))) * 180 / std::numbers::pi;
  const double least_spread_deg = least_rotation_spread_deg(params);
  if (!(r.rotation_spread_deg >= least_spread_deg)) {
    r.failure_reason = "the poses rotate too little about two axes (rotation spread " +
                       std::to_string(r.rotation_spread_deg) + " deg, at least " + std::to_string(least_spread_deg) +
                       " deg needed): the tip is not determined; pivot the tool about two different axes";
    return r;
  }
  const Vector6d x = eigen.eigenvectors() * (eigen.eigenvectors().transpose() * rhs).cwiseQuotient(eigen.eigenvalues());
  r.tip_in_tool = x.head<3>();
  r.pivot_in_tracker = x.tail<3>();
  double sum = 0;
  for (const Pose& T : tracker_from_tool) {
    const double e = (T * r.tip_in_tool - r.pivot_in_tracker).norm();
    sum += e * e;
    r.max_mm = std::max(r.max_mm, e);
  }
  r.rms_mm = std::sqrt(sum / double(n));
  r.ok = true;
  return r;
}

}  // namespace fluoro
