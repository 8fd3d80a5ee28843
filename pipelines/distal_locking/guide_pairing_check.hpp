#pragma once
// The guide's own check of a sphere pairing against its final pose, so that a wrong pairing is
// caught by the guide itself and not only, later, through the nail (docs/distal_locking.md: a
// pairing of 7 of 28 spheres, all visible, gave a pose 24 degrees off that only the nail's hole
// axes, 21 degrees from that guide's, revealed).
#include <Eigen/Core>
#include <string>
#include <vector>

#include "pipelines/distal_locking/pose_refinement.hpp"

namespace fluoro {

// One-to-one pairing of projected spheres with detections within `tol` pixels, nearest pairs
// first: per projected sphere the detection's index or -1; `count` the pairs.
std::vector<int> pair_nearest(const std::vector<Eigen::Vector2d>& projected, const std::vector<Eigen::Vector2d>& det,
                              double tol, int* count);

// The pose refitted on the pairs (`of`: per model sphere the detection, -1 none) within 3 robust
// sigmas of it (at least 0.25 px), if at least `min_pairs` are: a sphere on the nail's edge or
// touching another has its centroid pulled by the step under it (up to a pixel), an isolated one is
// within 0.01 px. Such pairs stay paired (the detection is that sphere's), counted in `outliers`.
CameraPose refit_without_outliers(const Eigen::Matrix3d& K, const CameraPose& pose, const std::vector<Eigen::Vector3d>& model,
                                  const std::vector<Eigen::Vector2d>& det, const std::vector<int>& of, int min_pairs,
                                  int* outliers);

struct CheckedPairing {
  bool ok = false;
  std::string failure_reason;
  CameraPose pose;
  std::vector<int> detection_of;  // per model sphere, -1 unpaired
  int pairs = 0;
  int in_image = 0;               // model spheres the pose puts inside the image
  int outliers = 0;               // pairs left out of the final fit (beyond 3 robust sigmas)
  int blobs = 0;                  // detections of two superimposed spheres, left unpaired
  double rms_px = 0;              // over all pairs
};

// Re-pairs every model sphere with the detections under the pose (within `tight_px`), refits the
// pose on the pairs within 3 robust sigmas, and repeats until the pairing no longer changes (at
// most 4 times): the pairing the final pose itself explains. A detection within one projected
// radius (`sphere_radius_mm` at its depth) of another sphere that has no detection of its own, and
// more than a quarter of the way from its own sphere's projection towards that one's, is the blob
// of both (two spheres nearly on one ray): ambiguous, it is left unpaired (`blobs`).
// Fails when the pairing explains fewer than half of the spheres the pose puts inside the image
// (`image_size` (0, 0): all count), or fewer than `min_pairs` within the robust cut.
CheckedPairing check_guide_pairing(const Eigen::Matrix3d& K, const std::vector<Eigen::Vector3d>& model,
                                   const std::vector<Eigen::Vector2d>& det, const CameraPose& pose, double tight_px,
                                   int min_pairs, const Eigen::Vector2i& image_size, double sphere_radius_mm);

// At least half of the spheres in view must be paired: the occlusion (up to 8 of 28) stays
// well inside, a pose from a few coincidental pairs (7 of 28) does not.
constexpr double kMinExplainedFraction = 0.5;

}  // namespace fluoro
