#include "pipelines/calibration/target_registration_error.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/LU>
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

double predicted_tre_rms_weighted(const std::vector<Eigen::Vector3d>& fiducials, const std::vector<double>& weights,
                                  const std::vector<double>& fle_rms_mm, const Eigen::Vector3d& target) {
  const size_t n = fiducials.size();
  if (n == 0 || weights.size() != n || fle_rms_mm.size() != n) return std::numeric_limits<double>::infinity();
  // Coordinates about the weighted centroid keep the normal equations well scaled.
  double total = 0;
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < n; ++i) total += weights[i], centroid += weights[i] * fiducials[i];
  if (!(total > 0)) return std::numeric_limits<double>::infinity();
  centroid /= total;
  // A small rotation w and translation v move fiducial p by -[p]_x w + v: row block A_i = [-[p]_x, I].
  const auto block = [](const Eigen::Vector3d& p) {
    Eigen::Matrix<double, 3, 6> a;
    a << 0, p.z(), -p.y(), 1, 0, 0,  //
        -p.z(), 0, p.x(), 0, 1, 0,   //
        p.y(), -p.x(), 0, 0, 0, 1;
    return a;
  };
  Eigen::Matrix<double, 6, 6> normal = Eigen::Matrix<double, 6, 6>::Zero(), noise = normal;
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Matrix<double, 3, 6> a = block(fiducials[i] - centroid);
    normal += weights[i] * a.transpose() * a;
    // Per-axis variance of an isotropic error whose RMS 3D length is fle: fle^2 / 3.
    noise += weights[i] * weights[i] * (fle_rms_mm[i] * fle_rms_mm[i] / 3) * a.transpose() * a;
  }
  const Eigen::FullPivLU<Eigen::Matrix<double, 6, 6>> lu(normal);
  if (!lu.isInvertible()) return std::numeric_limits<double>::infinity();
  const Eigen::Matrix<double, 6, 6> inverse = lu.inverse();
  const Eigen::Matrix<double, 3, 6> b = block(target - centroid);
  return std::sqrt(std::max(0.0, (b * inverse * noise * inverse * b.transpose()).trace()));
}

double fle_from_fre(double fre_rms_mm, size_t n) {
  if (n < 3) return std::numeric_limits<double>::infinity();
  return fre_rms_mm * std::sqrt(double(n) / double(n - 2));
}

}  // namespace fluoro
