#include "pipelines/calibration/projection_dlt.hpp"

#include <Eigen/Dense>
#include <cmath>
#include <limits>

namespace fluoro {

Eigen::Vector2d project_with(const Projection& P, const Eigen::Vector3d& x) {
  const Eigen::Vector3d p = P * x.homogeneous();
  if (!(p.z() > 0)) return Eigen::Vector2d::Constant(std::numeric_limits<double>::quiet_NaN());
  return p.head<2>() / p.z();
}

std::optional<Projection> projection_dlt(const std::vector<Eigen::Vector3d>& X,
                                         const std::vector<Eigen::Vector2d>& x) {
  const int n = int(X.size());
  if (n < 6 || int(x.size()) != n) return std::nullopt;
  Eigen::Vector3d mX = Eigen::Vector3d::Zero();
  Eigen::Vector2d mx = Eigen::Vector2d::Zero();
  for (int i = 0; i < n; ++i) mX += X[i], mx += x[i];
  mX /= n;
  mx /= n;
  double dX = 0, dx = 0;
  for (int i = 0; i < n; ++i) dX += (X[i] - mX).norm(), dx += (x[i] - mx).norm();
  if (!(dX > 0) || !(dx > 0)) return std::nullopt;
  const double sX = std::sqrt(3.0) * n / dX, sx = std::sqrt(2.0) * n / dx;
  Eigen::Matrix4d TX = Eigen::Matrix4d::Identity();
  TX.topLeftCorner<3, 3>() *= sX;
  TX.topRightCorner<3, 1>() = -sX * mX;
  Eigen::Matrix3d Tx = Eigen::Matrix3d::Identity();
  Tx.topLeftCorner<2, 2>() *= sx;
  Tx.topRightCorner<2, 1>() = -sx * mx;

  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(2 * n, 12);
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector4d Xn = TX * X[i].homogeneous();
    const Eigen::Vector2d xn = sx * (x[i] - mx);
    A.block<1, 4>(2 * i, 0) = Xn.transpose();
    A.block<1, 4>(2 * i, 8) = -xn.x() * Xn.transpose();
    A.block<1, 4>(2 * i + 1, 4) = Xn.transpose();
    A.block<1, 4>(2 * i + 1, 8) = -xn.y() * Xn.transpose();
  }
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(A, Eigen::ComputeFullV);
  const Eigen::VectorXd s = svd.singularValues();
  // A second (near) null vector means the pairs leave P undetermined (coplanar points admit a
  // family of solutions); with noise the two smallest values are then of the same, tiny order.
  if (!(s(10) > 1e-7 * s(0))) return std::nullopt;
  const Eigen::VectorXd p = svd.matrixV().col(11);
  Projection Pn;
  Pn << p.segment<4>(0).transpose(), p.segment<4>(4).transpose(), p.segment<4>(8).transpose();
  Projection P = Tx.inverse() * Pn * TX;
  P /= P.norm();
  int in_front = 0;
  for (int i = 0; i < n; ++i) in_front += (P.row(2).dot(X[i].homogeneous()) > 0) ? 1 : -1;
  if (in_front < 0) P = -P;
  return P;
}

}  // namespace fluoro
