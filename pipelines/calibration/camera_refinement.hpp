#pragma once
// Levenberg-Marquardt (Eigen's) on the reprojection error over the intrinsics (fx, fy, cx, cy;
// no skew) and the pose, from a starting camera such as the DLT's.
#include <Eigen/Core>
#include <vector>

#include "engine/camera.hpp"

namespace fluoro {

// The camera minimising the sum of squared pixel distances between `pixels` and the projections
// of `points`. The start's skew is dropped (a digital detector's is zero; the DLT's is noise).
// `iterations` receives the number of function evaluations when not null.
PinholeCamera refine_camera(const PinholeCamera& start, const std::vector<Eigen::Vector3d>& points,
                            const std::vector<Eigen::Vector2d>& pixels, int* evaluations = nullptr);

// One image's share of a joint refinement: its starting camera (its pose is refined on its own)
// and its pairs.
struct RefinementView {
  PinholeCamera start;
  std::vector<Eigen::Vector3d> points;
  std::vector<Eigen::Vector2d> pixels;
};

// Several images taken at one C-arm orientation share one K (fx, fy, cx, cy; no skew) and each
// has its own pose: LM over 4 + 6 x views parameters, from the mean of the starts' intrinsics.
// Returns one camera per view, all with the same K.
std::vector<PinholeCamera> refine_cameras_shared_intrinsics(const std::vector<RefinementView>& views);

}  // namespace fluoro
