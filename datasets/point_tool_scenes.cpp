#include "engine/random_draws.hpp"
#include "datasets/point_tool_scenes.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>

namespace fluoro {
namespace {

// The radial factor: bumps and a dent as Gaussians on the unit sphere of directions.
double lumpiness(const Eigen::Vector3d& d) {
  const auto bump = [&](const Eigen::Vector3d& centre, double width, double height) {
    return height * std::exp(-(d - centre.normalized()).squaredNorm() / (width * width));
  };
  return 1 + bump({0.8, 0.3, 0.5}, 0.35, 0.25) + bump({-0.4, 0.9, -0.2}, 0.5, 0.15) +
         bump({-0.3, -0.5, 0.8}, 0.3, 0.2) - bump({0.2, -0.9, -0.4}, 0.4, 0.12);
}

}  // namespace

TriangleMesh make_lumpy_surface(int rings) {
  rings = std::max(rings, 3);
  const int segments = 2 * rings;
  TriangleMesh mesh;
  const auto vertex = [&](double theta, double phi) -> Eigen::Vector3d {
    const Eigen::Vector3d d(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta));
    return Eigen::Vector3d(45 * d.x(), 30 * d.y(), 20 * d.z()) * lumpiness(d);
  };
  mesh.vertices.push_back(vertex(0, 0));  // north pole
  for (int i = 1; i < rings; ++i)
    for (int j = 0; j < segments; ++j)
      mesh.vertices.push_back(vertex(std::numbers::pi * i / rings, 2 * std::numbers::pi * j / segments));
  mesh.vertices.push_back(vertex(std::numbers::pi, 0));  // south pole
  const int south = int(mesh.vertices.size()) - 1;
  const auto at = [&](int ring, int j) { return 1 + (ring - 1) * segments + (j % segments); };
  for (int j = 0; j < segments; ++j) {
    mesh.triangles.push_back({0, at(1, j), at(1, j + 1)});
    mesh.triangles.push_back({south, at(rings - 1, j + 1), at(rings - 1, j)});
  }
  for (int i = 1; i + 1 < rings; ++i)
    for (int j = 0; j < segments; ++j) {
      mesh.triangles.push_back({at(i, j), at(i + 1, j), at(i + 1, j + 1)});
      mesh.triangles.push_back({at(i, j), at(i + 1, j + 1), at(i, j + 1)});
    }
  return mesh;
}

std::vector<Eigen::Vector3d> sample_surface(const TriangleMesh& mesh, size_t n, uint64_t seed) {
  std::vector<double> cumulative_area;
  double total = 0;
  for (const auto& t : mesh.triangles) {
    const Eigen::Vector3d &a = mesh.vertices[size_t(t[0])], &b = mesh.vertices[size_t(t[1])], &c = mesh.vertices[size_t(t[2])];
    total += 0.5 * (b - a).cross(c - a).norm();
    cumulative_area.push_back(total);
  }
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> uniform(0, 1);
  std::vector<Eigen::Vector3d> points;
  for (size_t k = 0; k < n; ++k) {
    const size_t t = size_t(std::lower_bound(cumulative_area.begin(), cumulative_area.end(), uniform(rng) * total) -
                            cumulative_area.begin());
    const auto& tri = mesh.triangles[std::min(t, mesh.triangles.size() - 1)];
    // Uniform on the triangle: reflect (u, v) back into the lower half of the unit square.
    double u = uniform(rng), v = uniform(rng);
    if (u + v > 1) u = 1 - u, v = 1 - v;
    const Eigen::Vector3d& a = mesh.vertices[size_t(tri[0])];
    points.push_back(a + u * (mesh.vertices[size_t(tri[1])] - a) + v * (mesh.vertices[size_t(tri[2])] - a));
  }
  return points;
}

std::vector<Pose> make_pivot_poses(const Eigen::Vector3d& tip_in_tool, const Eigen::Vector3d& pivot_in_tracker, size_t n,
                                   double max_angle_deg, double noise_mm, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> uniform(-1, 1);
  std::normal_distribution<double> gauss(0, 1);
  // The tool's base orientation: pointing down at the divot from above, turned about arbitrary axes.
  const Eigen::Matrix3d base = Eigen::AngleAxisd(2.0, Eigen::Vector3d(0.3, -0.5, 0.8).normalized()).toRotationMatrix();
  std::vector<Pose> poses;
  for (size_t i = 0; i < n; ++i) {
    Eigen::Vector3d axis = draw3(gauss, rng);
    const double angle = uniform(rng) * max_angle_deg * std::numbers::pi / 180;
    Pose T = Pose::Identity();
    T.linear() = Eigen::AngleAxisd(angle, axis.normalized()).toRotationMatrix() * base;
    T.translation() = pivot_in_tracker - T.linear() * tip_in_tool +
                      noise_mm * draw3(gauss, rng);
    poses.push_back(T);
  }
  return poses;
}

}  // namespace fluoro
