#pragma once
// Closed-form rigid registration of paired 3D points (Horn 1987, unit quaternions), with weights:
// the seed's initial pose from landmarks and its contact-based registration.
#include <Eigen/Core>
#include <string>
#include <vector>

#include "engine/pose.hpp"

namespace fluoro {

struct PointRegistration {
  Pose transform;        // maps `from` points onto `to` points
  double rms_mm = 0;     // weighted RMS residual (fiducial registration error)
  double max_mm = 0;     // largest residual
};

// The rigid T minimising sum w_i |T from_i - to_i|^2. Weights default to 1. Throws InputError
// naming `what` for mismatched sizes, fewer than 3 points, negative or non-finite weights, or
// points that are collinear (the rotation about their line is then undetermined).
PointRegistration register_points(const std::vector<Eigen::Vector3d>& from, const std::vector<Eigen::Vector3d>& to,
                                  const std::vector<double>& weights, const std::string& what);

}  // namespace fluoro
