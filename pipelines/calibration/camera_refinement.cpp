#include "pipelines/calibration/camera_refinement.hpp"

#include <Eigen/Geometry>
#include <unsupported/Eigen/LevenbergMarquardt>

#include "engine/pose.hpp"

namespace fluoro {
namespace {

// The reprojection residuals of one or more views: parameters fx, fy, cx, cy, then per view a
// rotation vector applied on top of that view's start R (near zero, far from its singularity) and t.
struct SharedReprojection : Eigen::DenseFunctor<double> {
  const std::vector<RefinementView>& views;
  std::vector<Eigen::Matrix3d> R0;
  static int residuals(const std::vector<RefinementView>& v) {
    int n = 0;
    for (const auto& x : v) n += 2 * int(x.points.size());
    return n;
  }
  SharedReprojection(const std::vector<RefinementView>& v, std::vector<Eigen::Matrix3d> r0)
      : DenseFunctor<double>(4 + 6 * int(v.size()), residuals(v)), views(v), R0(std::move(r0)) {}

  Eigen::Matrix3d R(const InputType& p, size_t k) const {
    return rotation_from_vector(p.segment<3>(4 + 6 * Eigen::Index(k))) * R0[k];
  }

  int operator()(const InputType& p, ValueType& f) const {
    Eigen::Index row = 0;
    for (size_t k = 0; k < views.size(); ++k) {
      const Eigen::Matrix3d r = R(p, k);
      const Eigen::Vector3d t = p.segment<3>(7 + 6 * Eigen::Index(k));
      for (size_t i = 0; i < views[k].points.size(); ++i) {
        const Eigen::Vector3d c = r * views[k].points[i] + t;
        f(row++) = p(0) * c.x() / c.z() + p(2) - views[k].pixels[i].x();
        f(row++) = p(1) * c.y() / c.z() + p(3) - views[k].pixels[i].y();
      }
    }
    return 0;
  }

  int df(const InputType& p, JacobianType& J) const {
    J.setZero();
    Eigen::Index row = 0;
    for (size_t k = 0; k < views.size(); ++k) {
      const Eigen::Matrix3d r = R(p, k);
      const Eigen::Index o = 4 + 6 * Eigen::Index(k);
      for (size_t i = 0; i < views[k].points.size(); ++i, row += 2) {
        const Eigen::Vector3d rx = r * views[k].points[i];
        const Eigen::Vector3d c = rx + p.segment<3>(o + 3);
        const double iz = 1.0 / c.z();
        J(row, 0) = c.x() * iz;
        J(row, 2) = 1;
        J(row + 1, 1) = c.y() * iz;
        J(row + 1, 3) = 1;
        Eigen::Matrix<double, 2, 3> dc;
        dc << p(0) * iz, 0, -p(0) * c.x() * iz * iz, 0, p(1) * iz, -p(1) * c.y() * iz * iz;
        Eigen::Matrix3d skew;
        skew << 0, -rx.z(), rx.y(), rx.z(), 0, -rx.x(), -rx.y(), rx.x(), 0;
        // A small rotation w on the left moves c by -[r X]_x w. For the rotation vector at p (not
        // only at 0) this is the left-increment derivative; LM only needs a descent direction that
        // is exact at convergence, and the second round restarts at zero.
        J.block<2, 3>(row, o) = -dc * skew;
        J.block<2, 3>(row, o + 3) = dc;
      }
    }
    return 0;
  }
};

// LM over the shared K and every view's pose, from the mean of the starts' intrinsics; two rounds,
// the second from the first's rotations, so the rotation vectors start again at zero.
std::vector<PinholeCamera> refine_views(const std::vector<RefinementView>& views, int* evaluations) {
  std::vector<PinholeCamera> cams;
  for (const auto& v : views) cams.push_back(v.start);
  if (views.empty()) return cams;
  Eigen::Vector4d k = Eigen::Vector4d::Zero();
  for (const auto& c : cams) k += Eigen::Vector4d(c.K(0, 0), c.K(1, 1), c.K(0, 2), c.K(1, 2));
  k /= double(cams.size());
  for (int round = 0; round < 2; ++round) {
    std::vector<Eigen::Matrix3d> r0;
    for (const auto& c : cams) r0.push_back(c.R);
    SharedReprojection f(views, r0);
    Eigen::VectorXd p = Eigen::VectorXd::Zero(f.inputs());
    p.head<4>() = k;
    for (size_t i = 0; i < cams.size(); ++i) p.segment<3>(7 + 6 * Eigen::Index(i)) = cams[i].t;
    Eigen::LevenbergMarquardt<SharedReprojection> lm(f);
    lm.setXtol(1e-14);
    lm.setFtol(1e-16);
    lm.setGtol(0);
    lm.setMaxfev(400);
    lm.minimize(p);
    if (evaluations) *evaluations += int(lm.nfev());
    k = p.head<4>();
    for (size_t i = 0; i < cams.size(); ++i) {
      cams[i].K << k(0), 0, k(2), 0, k(1), k(3), 0, 0, 1;
      cams[i].R = f.R(p, i);
      cams[i].t = p.segment<3>(7 + 6 * Eigen::Index(i));
    }
  }
  return cams;
}

}  // namespace

std::vector<PinholeCamera> refine_cameras_shared_intrinsics(const std::vector<RefinementView>& views) {
  return refine_views(views, nullptr);
}

PinholeCamera refine_camera(const PinholeCamera& start, const std::vector<Eigen::Vector3d>& points,
                            const std::vector<Eigen::Vector2d>& pixels, int* evaluations) {
  return refine_views({RefinementView{start, points, pixels}}, evaluations)[0];
}

}  // namespace fluoro
