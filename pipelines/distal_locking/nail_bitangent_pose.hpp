#pragma once
// The seed's generic-mode nail pose (section 4.4.3), for comparison with the cylinder fit
// (nail_pose.hpp): the nail's holes taken as two circles on its mid-plane; the outer common
// tangents (bitangents) of the two hole ellipses touch them at four points whose model positions
// are known, (x_k, +-r, 0) in the nail's frame (tangency is projective: the model circles' common
// tangents project onto the image ellipses'); the planar pose from those four by IPPE (OpenCV's
// solvePnP), its two-fold ambiguity resolved by the reprojection and then by the guide, as the seed
// does. It cannot see a hole's lens shrink and reads the outline as a planar circle.
#include <Eigen/Core>

#include "engine/distal_locking_models.hpp"
#include "pipelines/distal_locking/nail_detection.hpp"
#include "pipelines/distal_locking/nail_pose.hpp"

namespace fluoro {

// The four tangency points in the image, in the order (hole 0, side +), (hole 1, side +), (hole 0,
// side -), (hole 1, side -), the sides those of the band's left normal; false when the ellipses
// have no two outer common tangents (overlapping, or degenerate).
bool outer_bitangent_points(const HoleEllipse& a, const HoleEllipse& b, Eigen::Vector2d points[4]);

NailPoseEstimate bitangent_nail_pose(const NailDetection& detection, const NailModel& nail, const Eigen::Matrix3d& K,
                                     const Eigen::Vector3d& guide_x, const Eigen::Vector3d& guide_z);

}  // namespace fluoro
