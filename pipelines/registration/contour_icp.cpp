#include "pipelines/registration/contour_icp.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <tbb/parallel_for.h>

#include "engine/error.hpp"
#include "pipelines/registration/apparent_contour.hpp"
#include "pipelines/registration/nearest_point_map.hpp"

namespace fluoro {
namespace {

Eigen::Matrix3d skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d s;
  s << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return s;
}

// A pair: a mesh contour point (CT frame) and the ray it should lie on (world frame).
struct Pair {
  Eigen::Vector3d point_ct;
  Eigen::Vector3d source, direction;
  double distance = 0;
};

double ray_distance(const Eigen::Vector3d& q, const Pair& p) {
  const Eigen::Vector3d w = q - p.source;
  return (w - p.direction * p.direction.dot(w)).norm();
}

// Normal (unit) of the projected mesh contour edge at a contour point, or zero when degenerate.
Eigen::Vector2f projected_normal(const PinholeCamera& cam, const Pose& pose, const ContourPoint& c) {
  const Eigen::Vector2d a = cam.project(pose * (c.point - 0.5 * c.direction));
  const Eigen::Vector2d b = cam.project(pose * (c.point + 0.5 * c.direction));
  const Eigen::Vector2d d = b - a;
  const double n = d.norm();
  if (!(n > 1e-9)) return Eigen::Vector2f::Zero();
  return Eigen::Vector2f(float(-d.y() / n), float(d.x() / n));
}

}  // namespace

ContourIcpResult register_contours(const BoneMesh& mesh, std::span<const ContourData> views, const Pose& initial,
                                   const ContourIcpOptions& options) {
  if (views.empty()) throw InputError("contour registration: no views");
  struct ViewState {
    std::vector<Eigen::Vector3d> rays;  // world direction through each contour pixel
    NearestPointMap contour_map;        // mesh_to_contour: nearest contour pixel
  };
  std::vector<ViewState> state;
  for (size_t v = 0; v < views.size(); ++v) {
    const ContourData& d = views[v];
    if (d.pixels.empty()) throw InputError("contour registration: view " + std::to_string(v + 1) + " has no contour pixels");
    if (!d.normals.empty() && d.normals.size() != d.pixels.size())
      throw std::invalid_argument("register_contours: normals and pixels differ in number");
    ViewState s{{}, d.matching == ContourMatching::mesh_to_contour
                        ? NearestPointMap(d.pixels, d.camera.width, d.camera.height, /*remember_candidates=*/true)
                        : NearestPointMap({}, 1, 1)};
    s.rays.reserve(d.pixels.size());
    for (const auto& p : d.pixels) s.rays.push_back(d.camera.ray_direction(p.x(), p.y()));
    state.push_back(std::move(s));
  }
  // The mesh's centre and typical radius: rotations turn about the centre, and an update's size
  // is measured at the radius.
  const Eigen::Vector3d centre_ct = mesh.centroid();
  double radius = 0;
  for (const auto& p : mesh.vertices) radius += (p - centre_ct).norm();
  radius = mesh.vertices.empty() ? 1.0 : radius / double(mesh.vertices.size());

  ContourIcpResult result;
  result.pose = initial;
  std::vector<Pair> pairs;
  // Each iteration's pairing splits the mesh's edges into chunks, per view, scored in parallel
  // (on a head-sized CT's mesh it was most of the coarse step, on one core); the chunks' pairs are
  // joined in view and edge order, the serial loop's order, so the result is the same to the bit.
  constexpr size_t kChunk = 4096;
  const size_t chunks = std::max<size_t>(1, (mesh.edges.size() + kChunk - 1) / kChunk);
  struct ChunkOut {
    std::vector<ContourPoint> contour;  // contour_to_mesh views: the chunk's contour points
    std::vector<Pair> pairs;            // mesh_to_contour views: the chunk's pairs
  };
  std::vector<ChunkOut> out(views.size() * chunks);
  for (int it = 0; it < options.max_iterations; ++it) {
    pairs.clear();
    const Pose& pose = result.pose;
    const Pose inverse = pose.inverse();
    const auto agrees = [&](const ContourData& d, const ContourPoint& c, size_t pixel) {
      if (d.normals.empty()) return true;
      return std::abs(projected_normal(d.camera, pose, c).dot(d.normals[pixel])) >= options.normal_agreement;
    };
    tbb::parallel_for(size_t(0), out.size(), [&](size_t task) {
      const size_t v = task / chunks, chunk = task % chunks;
      const ContourData& d = views[v];
      const Eigen::Vector3d source = d.camera.source();
      const Eigen::Vector3d source_ct = inverse * source;
      ChunkOut& o = out[task];
      o.contour.clear();
      o.pairs.clear();
      ContourPoint c;
      const size_t end = std::min(mesh.edges.size(), (chunk + 1) * kChunk);
      for (size_t e = chunk * kChunk; e < end; ++e) {
        if (!on_apparent_contour(mesh, mesh.edges[e], source_ct, c)) continue;
        if (d.matching == ContourMatching::contour_to_mesh) {
          o.contour.push_back(c);
          continue;
        }
        const Eigen::Vector2d uv = d.camera.project(pose * c.point);
        const int k = state[v].contour_map.nearest(uv.x(), uv.y());
        if (k < 0 || !agrees(d, c, size_t(k))) continue;
        o.pairs.push_back({c.point, source, state[v].rays[size_t(k)]});
      }
    });
    for (size_t v = 0; v < views.size(); ++v) {
      const ContourData& d = views[v];
      if (d.matching == ContourMatching::mesh_to_contour) {
        for (size_t chunk = 0; chunk < chunks; ++chunk) {
          const std::vector<Pair>& p = out[v * chunks + chunk].pairs;
          pairs.insert(pairs.end(), p.begin(), p.end());
        }
        continue;
      }
      std::vector<ContourPoint> contour;
      for (size_t chunk = 0; chunk < chunks; ++chunk) {
        const std::vector<ContourPoint>& c = out[v * chunks + chunk].contour;
        contour.insert(contour.end(), c.begin(), c.end());
      }
      const Eigen::Vector3d source = d.camera.source();
      std::vector<Eigen::Vector2f> projected;
      projected.reserve(contour.size());
      for (const ContourPoint& c : contour) projected.push_back(d.camera.project(pose * c.point).cast<float>());
      const NearestPointMap mesh_map(projected, d.camera.width, d.camera.height);
      for (size_t k = 0; k < d.pixels.size(); ++k) {
        const int c = mesh_map.nearest(d.pixels[k].x(), d.pixels[k].y());
        if (c < 0 || !agrees(d, contour[size_t(c)], k)) continue;
        pairs.push_back({contour[size_t(c)].point, source, state[v].rays[k]});
      }
    }
    if (pairs.size() < 6) {
      if (it == 0) throw InputError("contour registration: the bone's contour projects outside every X-ray at the initial pose");
      break;
    }
    // Robust threshold from the median distance.
    std::vector<double> distances;
    distances.reserve(pairs.size());
    for (auto& p : pairs) {
      p.distance = ray_distance(pose * p.point_ct, p);
      distances.push_back(p.distance);
    }
    std::nth_element(distances.begin(), distances.begin() + distances.size() / 2, distances.end());
    const double median = distances[distances.size() / 2];
    const double threshold = std::max(options.min_inlier_mm, options.inlier_factor * median);

    // Gauss-Newton on sum |P (q - s)|^2 with q = pose * p, P = I - d d^T, for an update that
    // rotates by w about the mesh centre c and translates by t.
    const Eigen::Vector3d c = pose * centre_ct;
    Eigen::Matrix<double, 6, 6> H = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 1> g = Eigen::Matrix<double, 6, 1>::Zero();
    double sum_sq = 0;
    int inliers = 0;
    for (const Pair& p : pairs) {
      if (p.distance > threshold) continue;
      const Eigen::Vector3d q = pose * p.point_ct;
      const Eigen::Matrix3d P = Eigen::Matrix3d::Identity() - p.direction * p.direction.transpose();
      Eigen::Matrix<double, 3, 6> J;
      J << -P * skew(q - c), P;
      const Eigen::Vector3d r = P * (q - p.source);
      H.noalias() += J.transpose() * J;
      g.noalias() += J.transpose() * r;
      sum_sq += r.squaredNorm();
      ++inliers;
    }
    result.pairs = int(pairs.size());
    result.inliers = inliers;
    result.median_mm = median;
    result.rms_mm = inliers ? std::sqrt(sum_sq / inliers) : 0.0;
    result.iterations = it + 1;
    if (inliers < 6) break;
    // A little damping keeps directions the contours do not constrain where they are.
    H.diagonal().array() += 1e-9 * H.trace() + 1e-12;
    const Eigen::Matrix<double, 6, 1> delta = -H.ldlt().solve(g);
    if (!delta.allFinite()) break;
    const Eigen::Vector3d w = delta.head<3>(), t = delta.tail<3>();
    Pose update = pose_from_rotation_vector(w, Eigen::Vector3d::Zero());
    update.translation() = c + t - update.linear() * c;
    result.pose = update * pose;
    if (t.norm() + w.norm() * radius < options.tolerance_mm) {
      result.converged = true;
      break;
    }
  }
  return result;
}

}  // namespace fluoro
