#include "pipelines/calibration/camera_refinement.hpp"

#include <Eigen/Geometry>
#include <unsupported/Eigen/LevenbergMarquardt>

namespace fluoro {
namespace {

// Parameters: fx, fy, cx, cy, a rotation vector applied on top of the start's R, and t.
// Rotating about the start keeps the rotation vector near zero, far from its singularity.
struct Reprojection : Eigen::DenseFunctor<double> {
  const std::vector<Eigen::Vector3d>& X;
  const std::vector<Eigen::Vector2d>& x;
  Eigen::Matrix3d R0;
  Reprojection(const std::vector<Eigen::Vector3d>& points, const std::vector<Eigen::Vector2d>& pixels,
               const Eigen::Matrix3d& r0)
      : DenseFunctor<double>(10, 2 * int(points.size())), X(points), x(pixels), R0(r0) {}

  static Eigen::Matrix3d rotation(const Eigen::Vector3d& w) {
    const double a = w.norm();
    return a < 1e-300 ? Eigen::Matrix3d::Identity() : Eigen::AngleAxisd(a, w / a).toRotationMatrix();
  }
  Eigen::Matrix3d R(const InputType& p) const { return rotation(p.segment<3>(4)) * R0; }

  int operator()(const InputType& p, ValueType& f) const {
    const Eigen::Matrix3d r = R(p);
    for (size_t i = 0; i < X.size(); ++i) {
      const Eigen::Vector3d c = r * X[i] + p.segment<3>(7);
      f(2 * i) = p(0) * c.x() / c.z() + p(2) - x[i].x();
      f(2 * i + 1) = p(1) * c.y() / c.z() + p(3) - x[i].y();
    }
    return 0;
  }

  // Analytic Jacobian: d(u, v)/d(camera point) chained with the point's derivatives; a small
  // rotation w on the left moves c by -[r X]_x w.
  int df(const InputType& p, JacobianType& J) const {
    const Eigen::Matrix3d r = R(p);
    J.setZero();
    for (size_t i = 0; i < X.size(); ++i) {
      const Eigen::Vector3d rx = r * X[i];
      const Eigen::Vector3d c = rx + p.segment<3>(7);
      const double iz = 1.0 / c.z();
      J(2 * i, 0) = c.x() * iz;
      J(2 * i, 2) = 1;
      J(2 * i + 1, 1) = c.y() * iz;
      J(2 * i + 1, 3) = 1;
      Eigen::Matrix<double, 2, 3> dc;
      dc << p(0) * iz, 0, -p(0) * c.x() * iz * iz, 0, p(1) * iz, -p(1) * c.y() * iz * iz;
      Eigen::Matrix3d skew;
      skew << 0, -rx.z(), rx.y(), rx.z(), 0, -rx.x(), -rx.y(), rx.x(), 0;
      // For the rotation vector at p (not only at 0) this is the left-increment derivative; LM
      // only needs a descent direction that is exact at convergence, where it is re-linearised.
      J.block<2, 3>(2 * i, 4) = -dc * skew;
      J.block<2, 3>(2 * i, 7) = dc;
    }
    return 0;
  }
};

}  // namespace

PinholeCamera refine_camera(const PinholeCamera& start, const std::vector<Eigen::Vector3d>& points,
                            const std::vector<Eigen::Vector2d>& pixels, int* evaluations) {
  PinholeCamera cam = start;
  // Two rounds: the second starts from the first's rotation, so its rotation vector is again ~0
  // and the left-increment Jacobian is exact where it matters.
  for (int round = 0; round < 2; ++round) {
    Reprojection f(points, pixels, cam.R);
    Eigen::VectorXd p(10);
    p << cam.K(0, 0), cam.K(1, 1), cam.K(0, 2), cam.K(1, 2), 0, 0, 0, cam.t;
    Eigen::LevenbergMarquardt<Reprojection> lm(f);
    lm.setXtol(1e-14);
    lm.setFtol(1e-16);
    lm.setGtol(0);
    lm.setMaxfev(400);
    lm.minimize(p);
    if (evaluations) *evaluations += int(lm.nfev());
    cam.K << p(0), 0, p(2), 0, p(1), p(3), 0, 0, 1;
    cam.R = f.R(p);
    cam.t = p.segment<3>(7);
  }
  return cam;
}

}  // namespace fluoro
