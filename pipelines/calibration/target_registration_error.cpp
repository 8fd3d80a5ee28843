#include "pipelines/calibration/target_registration_error.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>

namespace fluoro {

double predicted_tre_rms(const std::vector<Eigen::Vector3d>& fiducials, const Eigen::Vector3d& target, double fle_rms_mm) {
  const size_t n = fiducials.size();
  if (n == 0) return std::numeric_limits<double>::infinity();
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (const auto& f : fiducials) centroid += f;
  centroid /= double(n);
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (const auto& f : fiducials) scatter += (f - centroid) * (f - centroid).transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> principal(scatter);
  const Eigen::Vector3d r = target - centroid;
  double sum = 0;
  for (int k = 0; k < 3; ++k) {
    const Eigen::Vector3d axis = principal.eigenvectors().col(k);
    // Squared distance from axis k is the squared length minus the squared projection on it.
    double f2 = 0;
    for (const auto& f : fiducials) {
      const Eigen::Vector3d d = f - centroid;
      f2 += d.squaredNorm() - std::pow(d.dot(axis), 2);
    }
    f2 /= double(n);
    const double d2 = std::max(0.0, r.squaredNorm() - std::pow(r.dot(axis), 2));
    if (!(f2 > 0)) return std::numeric_limits<double>::infinity();  // collinear fiducials
    sum += d2 / f2;
  }
  return std::sqrt(fle_rms_mm * fle_rms_mm / double(n) * (1 + sum / 3));
}

double fle_from_fre(double fre_rms_mm, size_t n) {
  if (n < 3) return std::numeric_limits<double>::infinity();
  return fre_rms_mm * std::sqrt(double(n) / double(n - 2));
}

}  // namespace fluoro
