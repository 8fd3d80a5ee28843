#pragma once
// Distal locking from one X-ray (the seed's chapter 4): the drill guide's pose, the nail's pose in
// the generic (single image, any view) or interactive (fronto-parallel) mode, and where each hole's
// axis enters and leaves the nail, all in the camera file's world frame.
#include <Eigen/Geometry>
#include <optional>
#include <string>
#include <vector>

#include "engine/camera.hpp"
#include "engine/distal_locking_models.hpp"
#include "engine/image.hpp"
#include "pipelines/distal_locking/guide_localisation.hpp"
#include "pipelines/distal_locking/nail_detection.hpp"
#include "pipelines/distal_locking/nail_pose.hpp"

namespace fluoro {

enum class NailMode { generic, interactive };

// Per hole, in NAIL.json's order, in the world frame.
struct HoleAxisPoints {
  Eigen::Vector3d entry_mm;  // where the hole's axis meets the nail's surface on the guide's side
  Eigen::Vector3d exit_mm;   // the opposite side
  double circularity = 0;    // minor / major axis of the hole's see-through lens in the image
  double deviation_deg = 0;  // between the hole's axis and the ray from the source through its centre
};

struct DistalLocking {
  bool ok = false;             // both poses found
  std::string failure_reason;  // why not
  GuideDetection guide;
  bool guide_ok = false;
  NailDetection nail_detection;
  NailPoseEstimate nail_pose;
  bool nail_ok = false;
  Eigen::Isometry3d T_world_guide = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_world_nail = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_camera_guide = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_camera_nail = Eigen::Isometry3d::Identity();
  std::vector<HoleAxisPoints> holes;
  // The angle between the hole axes (the generic fit's, in both modes) and the ray from the source
  // through the nail's centre: what the interactive mode assumes to be 0. A view within
  // kFrontoParallelDeg is one the interactive mode accepts as fronto-parallel.
  double view_deviation_deg = 0;
  bool fronto_parallel = false;
  double spheres_seconds = 0, nail_detection_seconds = 0, nail_pose_seconds = 0;
};

// The interactive mode's acceptance of a view: hole axes within 1 degree of the ray through the
// nail's centre (what it then assumes is 0; each hole's own ray is a further 1.0-1.4 degrees off at
// 600-850 mm, the holes being 15 mm from the centre, which no view can remove for both).
constexpr double kFrontoParallelDeg = 1.0;

// The generic mode's limit on a tie the guide decides (NailPoseEstimate::tie_spread_deg): fits
// further apart than this that the image cannot tell apart make the nail's pose a guess between
// them, flagged (status failed) rather than reported. 1 degree: the hole axis's accuracy the
// method is held to (docs/distal_locking.md, "Measured").
constexpr double kMaxTieSpreadDeg = 1.0;

// The nail is looked for between 300 and 1500 mm from the source (its image width follows).
DistalLocking locate_for_distal_locking(const Image& xray, const PinholeCamera& camera, const DrillGuideModel& guide,
                                        const NailModel& nail, NailMode mode);

}  // namespace fluoro
