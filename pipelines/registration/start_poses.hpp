#pragma once
// Start poses at a controlled distance from the truth, for robustness sweeps (seed, chapter 2,
// fig. 7): a random rotation about the bone centre and a random translation, scaled so the mean
// surface TRE of the start pose equals the requested distance.
#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "engine/pose.hpp"

namespace fluoro {

struct StartPoseParams {
  double max_rotation_deg = 45.0;  // rotations larger than this are redrawn
};

// A T_world_ct whose mean distance to `truth` over `surface_ct` (CT-frame points) is
// `distance_mm` (to 1e-3 mm). Deterministic in `seed`. `centre_ct` is the rotation centre.
Pose start_pose_at_distance(const Pose& truth, const std::vector<Eigen::Vector3d>& surface_ct,
                            const Eigen::Vector3d& centre_ct, double distance_mm, uint64_t seed,
                            const StartPoseParams& params = {});

}  // namespace fluoro
