#include "pipelines/calibration/pivot_calibration.hpp"

#include <Eigen/SVD>
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
  // R_i tip - pivot = -p_i, stacked: A x = b with x = (tip, pivot).
  Eigen::MatrixXd A(3 * n, 6);
  Eigen::VectorXd b(3 * n);
  for (size_t i = 0; i < n; ++i) {
    A.block<3, 3>(3 * i, 0) = tracker_from_tool[i].linear();
    A.block<3, 3>(3 * i, 3) = -Eigen::Matrix3d::Identity();
    b.segment<3>(3 * i) = -tracker_from_tool[i].translation();
  }
  const Eigen::BDCSVD<Eigen::MatrixXd> svd(A, Eigen::ComputeThinU | Eigen::ComputeThinV);
  const double sigma_min = svd.singularValues()(5);
  r.rotation_spread_deg = 2 * std::asin(std::min(1.0, sigma_min / std::sqrt(double(n)))) * 180 / std::numbers::pi;
  if (!(r.rotation_spread_deg >= params.min_rotation_spread_deg)) {
    r.failure_reason = "the poses rotate too little about two axes (rotation spread " +
                       std::to_string(r.rotation_spread_deg) + " deg, at least " +
                       std::to_string(params.min_rotation_spread_deg) +
                       " deg needed): the tip is not determined; pivot the tool about two different axes";
    return r;
  }
  const Eigen::VectorXd x = svd.solve(b);
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
