#include "pipelines/registration/triangulation.hpp"

#include <Eigen/Dense>
#include <cmath>

#include "engine/error.hpp"

namespace fluoro {

Triangulation triangulate(const std::vector<PinholeCamera>& cameras, const std::vector<Eigen::Vector2d>& pixels,
                          const std::string& what) {
  if (cameras.size() != pixels.size())
    throw_input_error(what, std::to_string(pixels.size()) + " pixel positions for " + std::to_string(cameras.size()) + " views");
  if (cameras.size() < 2) throw_input_error(what, "a point needs at least two views to triangulate");
  // Minimise sum_j |(I - d_j d_j^T)(x - c_j)|^2: the normal equations are 3x3.
  Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  std::vector<Eigen::Vector3d> centres, dirs;
  for (size_t j = 0; j < cameras.size(); ++j) {
    if (!pixels[j].allFinite()) throw_input_error(what, "pixel position in view " + std::to_string(j) + " is not finite");
    const Eigen::Vector3d c = cameras[j].source(), d = cameras[j].ray_direction(pixels[j].x(), pixels[j].y());
    const Eigen::Matrix3d P = Eigen::Matrix3d::Identity() - d * d.transpose();
    A += P;
    b += P * c;
    centres.push_back(c);
    dirs.push_back(d);
  }
  // Parallel rays leave A with a (near) zero eigenvalue along their direction. 1 degree between
  // two rays gives a smallest eigenvalue of about sin^2(1 deg) / 2 = 1.5e-4.
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(A);
  if (eig.eigenvalues()(0) < 1.5e-4)
    throw_input_error(what, "the views' rays are nearly parallel: the point's depth is undetermined");
  Triangulation t;
  t.point = A.ldlt().solve(b);
  double sum = 0;
  for (size_t j = 0; j < centres.size(); ++j) {
    const Eigen::Vector3d v = t.point - centres[j];
    sum += (v - v.dot(dirs[j]) * dirs[j]).squaredNorm();
  }
  t.rms_ray_distance_mm = std::sqrt(sum / double(centres.size()));
  return t;
}

}  // namespace fluoro
