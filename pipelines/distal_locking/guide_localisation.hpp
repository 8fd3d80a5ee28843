#pragma once
// The drill guide in one X-ray, the camera's K known: its steel spheres found as dark circles
// (pipelines/calibration/dark_circle_detector), paired with GUIDE.json by hypothesise and verify
// (P3P on a model sphere and its two nearest neighbours against a detection and two of its nearest
// detections; every pose projects all spheres and counts the detections it explains), then the
// pose by Levenberg-Marquardt on the reprojection error of the pairs.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <optional>
#include <string>
#include <vector>

#include "engine/distal_locking_models.hpp"
#include "engine/image.hpp"
#include "pipelines/calibration/dark_circle_detector.hpp"
#include "pipelines/distal_locking/pose_refinement.hpp"

namespace fluoro {

struct GuideMatchingParams {
  double tight_tolerance_px = 1.5;  // a verified pair's distance under the refined pose
  int min_pairs = 6;
  Eigen::Vector2i image_size = Eigen::Vector2i::Zero();  // (0, 0): not known, every sphere counts as in view
};

// The guide's pose in the camera frame and which detection each model sphere is paired with.
struct GuideLocalisation {
  bool ok = false;
  std::string failure_reason;
  CameraPose T_camera_guide = CameraPose::Identity();
  std::vector<int> detection_of;     // per model sphere: index into `circles`, -1 unpaired
  std::vector<int> matched_ids;      // model spheres paired, ascending
  double rms_px = 0, max_px = 0;
  int second_best_pairs = 0;         // the best pairing that disagrees with the chosen one
  int outlier_pairs = 0;             // paired, but beyond 3 robust sigmas: left out of the pose's fit
};

// Pairs detected sphere centres with the model under known K. Fails (ok = false, a reason) when no
// hypothesis explains at least `min_pairs` spheres, when two different pairings explain as many, or
// when the pairing the final pose explains covers fewer than half of the spheres it puts in the
// image (guide_pairing_check.hpp).
GuideLocalisation match_guide(const DrillGuideModel& guide, const std::vector<Eigen::Vector2d>& centres,
                              const Eigen::Matrix3d& K, const GuideMatchingParams& params = {});

// Detection with radii set from the guide's sphere size at a plausible depth range, then matching.
struct GuideDetection {
  std::vector<DarkCircle> circles;
  GuideLocalisation localisation;
};
GuideDetection localise_guide(const Image& xray, const DrillGuideModel& guide, const Eigen::Matrix3d& K);

}  // namespace fluoro
