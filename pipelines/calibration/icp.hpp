#pragma once
// Trimmed point-to-plane ICP of a point cloud (world frame) to a surface mesh (model frame, e.g.
// a CT's): the pose T_world_model that puts the model's surface through the points.
#include <Eigen/Core>
#include <string>
#include <vector>

#include "engine/pose.hpp"
#include "kernels/mesh/closest_point.hpp"

namespace fluoro {

// Trimming and stopping. Each iteration keeps the keep_fraction of pairs nearest the surface, so
// up to 1 - keep_fraction of the points may be outliers (points off the bone, mis-digitised).
struct IcpParams {
  double keep_fraction = 0.9;
  int max_iterations = 100;
  double min_rotation_step_deg = 1e-4;    // converged when one step moves less than both, or
                                          // lowers the trimmed objective by under 1e-8 of it
  double min_translation_step_mm = 1e-4;
  size_t min_points = 6;                  // kept pairs needed for the 6 pose parameters
  double min_constraint_ratio = 1e-3;     // smallest / largest eigenvalue of the step's normal matrix
};

// The pose with the residuals at it: rms_mm over the kept pairs (3D point-to-surface distances),
// inlier_fraction of all points within 3 rms_mm (at least 0.01 mm) of the surface. ok = false
// with a reason when the points are too few, the surface does not constrain the pose, or the
// iteration did not converge.
struct IcpResult {
  bool ok = false;
  std::string failure_reason;
  Pose T_world_model = Pose::Identity();
  double rms_mm = 0;
  double inlier_fraction = 0;
  size_t kept = 0;
  int iterations = 0;
};

IcpResult icp_point_to_plane(const MeshClosestPoint& model, const std::vector<Eigen::Vector3d>& world_points,
                             const Pose& initial_T_world_model, const IcpParams& params = {});

}  // namespace fluoro
