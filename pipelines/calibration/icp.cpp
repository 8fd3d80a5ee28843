#include "pipelines/calibration/icp.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <numeric>

#include "pipelines/registration/point_registration.hpp"

namespace fluoro {
namespace {

// Indices of the `keep` pairs nearest the surface.
std::vector<size_t> nearest_pairs(const std::vector<SurfacePoint>& closest, size_t keep) {
  if (keep == 0) return {};
  std::vector<size_t> order(closest.size());
  std::iota(order.begin(), order.end(), size_t(0));
  std::nth_element(order.begin(), order.begin() + std::ptrdiff_t(keep - 1), order.end(),
                   [&](size_t a, size_t b) { return closest[a].distance < closest[b].distance; });
  order.resize(keep);
  return order;
}

std::vector<Eigen::Vector3d> to_model(const Pose& model_from_world, const std::vector<Eigen::Vector3d>& world) {
  std::vector<Eigen::Vector3d> out(world.size());
  for (size_t i = 0; i < world.size(); ++i) out[i] = model_from_world * world[i];
  return out;
}

// The points in the model's frame at a pose, their closest surface points, the kept (nearest)
// pairs and the trimmed objective: the kept pairs' sum of squared distances.
struct State {
  std::vector<Eigen::Vector3d> q;
  std::vector<SurfacePoint> closest;
  std::vector<size_t> kept;
  double objective = 0;
};

// `previous`: the closest points at a nearby pose (empty for none); they bound the search.
State evaluate(const MeshClosestPoint& model, const std::vector<Eigen::Vector3d>& world_points,
               const Pose& model_from_world, size_t keep, const std::vector<SurfacePoint>& previous = {}) {
  State s;
  s.q = to_model(model_from_world, world_points);
  s.closest = model.closest(s.q, previous);
  s.kept = nearest_pairs(s.closest, keep);
  for (size_t i : s.kept) s.objective += s.closest[i].distance * s.closest[i].distance;
  return s;
}

}  // namespace

IcpResult icp_point_to_plane(const MeshClosestPoint& model, const std::vector<Eigen::Vector3d>& world_points,
                             const Pose& initial_T_world_model, const IcpParams& params) {
  IcpResult r;
  const size_t n = world_points.size();
  const size_t keep = std::min(n, size_t(std::ceil(std::clamp(params.keep_fraction, 0.0, 1.0) * double(n))));
  if (keep < params.min_points) {
    r.failure_reason = std::to_string(n) + " points keep " + std::to_string(keep) + " pairs after trimming, at least " +
                       std::to_string(params.min_points) + " are needed for a rigid pose";
    return r;
  }
  // The model stays put (its index is built once); the points move into the model's frame.
  Pose model_from_world = initial_T_world_model.inverse();
  State state = evaluate(model, world_points, model_from_world, keep);
  bool converged = false;
  for (r.iterations = 1; r.iterations <= params.max_iterations; ++r.iterations) {
    const std::vector<Eigen::Vector3d>& q = state.q;
    const std::vector<SurfacePoint>& closest = state.closest;
    const std::vector<size_t>& kept = state.kept;

    // Linearised point-to-plane step about the kept points' centroid g (rotation and translation
    // then barely couple): minimise sum (n . (q + w x (q - g) + v - c))^2 over (w, v).
    Eigen::Vector3d g = Eigen::Vector3d::Zero();
    for (size_t i : kept) g += q[i];
    g /= double(keep);
    double radius2 = 0;
    for (size_t i : kept) radius2 += (q[i] - g).squaredNorm();
    const double radius = std::max(std::sqrt(radius2 / double(keep)), 1e-9);
    Eigen::Matrix<double, 6, 6> JtJ = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 1> Jtr = Eigen::Matrix<double, 6, 1>::Zero();
    for (size_t i : kept) {
      // The plane through c perpendicular to q - c: the distance's own linearisation. It is the
      // triangle's plane when c is inside a face, and stays right when c is on an edge or a
      // vertex, where the face normal would misdirect the step.
      const Eigen::Vector3d offset = q[i] - closest[i].point;
      const double d = offset.norm();
      const Eigen::Vector3d nrm = d > 1e-9 ? Eigen::Vector3d(offset / d) : closest[i].normal;
      Eigen::Matrix<double, 6, 1> row;
      // Rotation columns scaled by the cloud's radius so that all six are in mm.
      row << (q[i] - g).cross(nrm) / radius, nrm;
      const double residual = nrm.dot(q[i] - closest[i].point);
      JtJ += row * row.transpose();
      Jtr += row * residual;
    }
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>> eig(JtJ);
    // The weakest combination of the six parameters (rotations in mm at the cloud's radius) must
    // be constrained at least 1e-3 as strongly as the strongest; below that, noise and the mesh's
    // faceting decide it (an asymmetric bone gives 0.04 to 0.07, a sphere of 60 rings 4e-4).
    if (!(eig.eigenvalues()(0) > params.min_constraint_ratio * eig.eigenvalues()(5))) {
      r.failure_reason = "the surface does not constrain the pose (a plane, sphere or surface of revolution under the points)";
      return r;
    }
    const Eigen::Matrix<double, 6, 1> step = -JtJ.ldlt().solve(Jtr);

    // The step is taken only if it lowers the trimmed sum of squared point-to-surface distances,
    // halved a few times until it does. Plain point-to-plane ICP with re-trimming can cycle (a
    // point at the trimming boundary swapping in and out, seen with 15 points), and far from the
    // surface its planes mislead; a monotone objective can do neither.
    bool accepted = false;
    Pose delta = Pose::Identity();
    State candidate;
    for (double scale = 1; scale > 0.1 && !accepted; scale *= 0.5) {
      const Eigen::Vector3d w = scale * step.head<3>() / radius, v = scale * step.tail<3>();
      delta = Pose::Identity();
      if (w.norm() > 0) delta.linear() = Eigen::AngleAxisd(w.norm(), w.normalized()).toRotationMatrix();
      delta.translation() = g + v - delta.linear() * g;
      candidate = evaluate(model, world_points, delta * model_from_world, keep, closest);
      accepted = candidate.objective < state.objective;
    }
    if (!accepted) {
      // Point-to-point (Horn) onto the kept pairs' closest points: classic ICP, which never
      // raises the objective (the fit lowers it for these pairs, new closest points and new
      // trimming lower it further).
      std::vector<Eigen::Vector3d> from, to;
      for (size_t i : kept) {
        from.push_back(q[i]);
        to.push_back(closest[i].point);
      }
      delta = register_points(from, to, {}, "icp").transform;
      candidate = evaluate(model, world_points, delta * model_from_world, keep, closest);
      accepted = candidate.objective < state.objective;
    }
    // Nothing lowers the objective: a (local) minimum.
    if (!accepted) {
      converged = true;
      break;
    }
    const double decrease = state.objective - candidate.objective;
    model_from_world = delta * model_from_world;
    state = std::move(candidate);
    // The step's size: its rotation, and how far it moved the kept points' centroid.
    const double step_deg = rotation_angle_deg(delta);
    const double step_mm = (delta * g - g).norm();
    if ((step_deg < params.min_rotation_step_deg && step_mm < params.min_translation_step_mm) ||
        decrease <= 1e-8 * state.objective) {
      converged = true;
      break;
    }
  }
  if (!converged) {
    r.iterations = params.max_iterations;
    r.failure_reason = "did not converge in " + std::to_string(params.max_iterations) + " iterations";
    return r;
  }

  // Residuals at the final pose.
  r.T_world_model = model_from_world.inverse();
  const std::vector<SurfacePoint>& closest = state.closest;
  r.rms_mm = std::sqrt(state.objective / double(keep));
  r.kept = keep;
  size_t inliers = 0;
  // The 0.01 mm floor keeps exact data from counting float rounding as outliers.
  const double inlier_distance = std::max(3 * r.rms_mm, 0.01);
  for (const SurfacePoint& s : closest) inliers += s.distance <= inlier_distance ? 1 : 0;
  r.inlier_fraction = double(inliers) / double(n);
  r.ok = true;
  return r;
}

}  // namespace fluoro
