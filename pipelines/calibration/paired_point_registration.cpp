#include "pipelines/calibration/paired_point_registration.hpp"

#include <Eigen/Eigenvalues>
#include <cmath>

#include "pipelines/calibration/target_registration_error.hpp"
#include "pipelines/registration/point_registration.hpp"

namespace fluoro {

std::string rotation_degeneracy(const std::vector<Eigen::Vector3d>& points) {
  if (points.size() < 3) return "a rigid registration needs at least 3 point pairs, got " + std::to_string(points.size());
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (const auto& p : points) centroid += p;
  centroid /= double(points.size());
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (const auto& p : points) scatter += (p - centroid) * (p - centroid).transpose();
  const Eigen::Vector3d spread = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(scatter).eigenvalues();
  // The points' RMS distance from their best line against their RMS extent along it: below
  // 0.1 % the rotation about the line is decided by noise alone.
  if (!(spread(2) > 0) || std::sqrt(std::max(0.0, spread(1)) / spread(2)) < 1e-3)
    return "the points are collinear (or coincident): the rotation about their line is undetermined";
  return "";
}

PairedRegistration register_paired_points(const std::vector<Eigen::Vector3d>& fixed,
                                          const std::vector<Eigen::Vector3d>& moving,
                                          const std::vector<Eigen::Vector3d>& targets,
                                          std::optional<double> fle_rms_mm, const std::vector<double>& weights) {
  PairedRegistration r;
  if (std::string why = rotation_degeneracy(moving); !why.empty()) {
    r.failure_reason = "moving points: " + why;
    return r;
  }
  if (std::string why = rotation_degeneracy(fixed); !why.empty()) {
    r.failure_reason = "fixed points: " + why;
    return r;
  }
  const PointRegistration reg = register_points(moving, fixed, weights, "register-points");
  r.T_fixed_moving = reg.transform;
  r.fre_rms_mm = reg.rms_mm;
  r.fre_max_mm = reg.max_mm;
  r.fle_estimated = !fle_rms_mm.has_value();
  r.fle_rms_mm = fle_rms_mm ? *fle_rms_mm : fle_from_fre(reg.rms_mm, moving.size());
  if (weights.empty()) {
    for (const auto& t : targets) r.predicted_tre_rms_mm.push_back(predicted_tre_rms(moving, t, r.fle_rms_mm));
  } else {
    // FLE_i^2 proportional to 1 / w_i, with mean FLE_i^2 = FLE^2.
    double mean_inverse = 0;
    for (double w : weights) mean_inverse += 1 / w;
    mean_inverse /= double(weights.size());
    std::vector<double> fle_i;
    for (double w : weights) fle_i.push_back(r.fle_rms_mm * std::sqrt((1 / w) / mean_inverse));
    for (const auto& t : targets) r.predicted_tre_rms_mm.push_back(predicted_tre_rms_weighted(moving, weights, fle_i, t));
  }
  r.ok = true;
  return r;
}

}  // namespace fluoro
