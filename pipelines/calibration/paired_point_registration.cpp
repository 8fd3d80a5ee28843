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

namespace {

// mean_i(1 / w_i) over n points (1 without weights): FLE_i^2 = FLE^2 (1 / w_i) / mean(1 / w).
double mean_inverse_weight(const std::vector<double>& weights, size_t n) {
  if (weights.empty()) return 1.0;
  double sum = 0;
  for (double w : weights) sum += 1 / w;
  return sum / double(n);
}

// The RMS TRE at each target for an RMS FLE of `fle` (equal weights: Fitzpatrick-West; else
// FLE_i^2 proportional to 1 / w_i, with mean FLE_i^2 = FLE^2, by first-order propagation).
std::vector<double> predicted_tres(const std::vector<Eigen::Vector3d>& moving, const std::vector<double>& weights,
                                   const std::vector<Eigen::Vector3d>& targets, double fle) {
  std::vector<double> tre;
  if (weights.empty()) {
    for (const auto& t : targets) tre.push_back(predicted_tre_rms(moving, t, fle));
    return tre;
  }
  const double mean_inverse = mean_inverse_weight(weights, weights.size());
  std::vector<double> fle_i;
  for (double w : weights) fle_i.push_back(fle * std::sqrt((1 / w) / mean_inverse));
  for (const auto& t : targets) tre.push_back(predicted_tre_rms_weighted(moving, weights, fle_i, t));
  return tre;
}

// The 99.9 % quantile of chi^2 with k degrees of freedom (Wilson-Hilferty: at most 2 % above the
// exact one for k >= 3, the fewest that three point pairs give: 16.55 against 16.27 there, 22.68
// against 22.46 at k = 6), so the test errs by that much towards accepting.
double chi2_quantile_999(double k) {
  const double z = 3.090232, a = 2 / (9 * k);
  return k * std::pow(1 - a + z * std::sqrt(a), 3);
}

}  // namespace

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
  r.predicted_tre_rms_mm = predicted_tres(moving, weights, targets, r.fle_rms_mm);
  if (fle_rms_mm) {
    FleCheck c;
    // sum_i w_i |e_i|^2 / mean(1 / w): the residuals in units where FLE_i^2 = FLE^2 (1 / w_i) / mean(1 / w).
    double weighted = 0;
    for (size_t i = 0; i < moving.size(); ++i)
      weighted += (weights.empty() ? 1.0 : weights[i]) * (r.T_fixed_moving * moving[i] - fixed[i]).squaredNorm();
    const double dof = 3.0 * double(moving.size()) - 6.0, sum = weighted * mean_inverse_weight(weights, moving.size());
    c.fle_from_residuals_mm = std::sqrt(3 * sum / dof);
    c.chi2 = sum == 0 ? 0.0 : 3 * sum / (*fle_rms_mm * *fle_rms_mm);
    c.chi2_limit = chi2_quantile_999(dof);
    c.consistent = c.chi2 <= c.chi2_limit;
    if (!c.consistent) c.predicted_tre_rms_mm = predicted_tres(moving, weights, targets, c.fle_from_residuals_mm);
    r.fle_check = c;
  }
  r.ok = true;
  return r;
}

}  // namespace fluoro
