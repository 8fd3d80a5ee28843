#pragma once
// The robot's goal (the seed's transformation chain, figure 4.4): the pose of the robot's tip in
// its base frame at which the drill guide's two axes lie on the nail's two hole axes, from the
// guide's and the nail's poses in the camera frame and the robot's current and mounting transforms.
#include <Eigen/Geometry>
#include <optional>
#include <string>

#include "engine/distal_locking_models.hpp"

namespace fluoro {

// The guide's axes (two, parallel) and the nail's holes (two) as frames: origin midway between the
// two axes (at the guide's axis points, the holes' centres), z along the axes, x from the first
// axis to the second. Throws InputError naming `guide_what` / `nail_what` when the guide does not
// have exactly two parallel axes (within 0.5 degrees) or the nail two holes.
Eigen::Isometry3d guide_axes_frame(const DrillGuideModel& guide, const std::string& guide_what);
Eigen::Isometry3d nail_holes_frame(const NailModel& nail, const std::string& nail_what);

// The guide's axes' spacing minus the nail's holes' (mm): a goal can put both axes on both holes
// only when it is about 0.
double guide_nail_spacing_mismatch_mm(const DrillGuideModel& guide, const NailModel& nail);

// The most spacing mismatch a robot's goal is given for: the goal shares the axes' and the holes'
// midline, so each axis then misses its hole's centre by half of it (0.25 mm: the clearance of a
// 4.5 mm screw in a 5 mm hole). Beyond it the guide is not one for this nail. A fixed limit, not
// one from NAIL.json's hole diameter: it says whether the guide was made for these holes' spacing,
// not whether a drill would still pass.
constexpr double kMaxSpacingMismatchMm = 0.5;

// Throws InputError naming `guide_what` when the guide's axes and the nail's holes are spaced more
// than kMaxSpacingMismatchMm apart (after guide_axes_frame's and nail_holes_frame's checks).
void check_guide_fits_nail(const DrillGuideModel& guide, const NailModel& nail, const std::string& guide_what,
                           const std::string& nail_what);

struct RobotGoal {
  Eigen::Isometry3d T_base_goal;
  double slide_mm = 0;          // along the axes, from the holes' centres to the guide's axis points
  double turn_from_now_deg = 0; // rotation between the current tip pose and the goal
  double spacing_mismatch_mm = 0;  // guide axes' spacing minus the holes' (axes then share a midline)
};

// Poses that put the axes on the holes differ by a slide along them and turns of 180 degrees
// (swapping which axis meets which hole, or reversing the drilling direction); the one nearest
// the current T_base_tip is returned: the smallest turn, then the slide that moves the tip least.
RobotGoal robot_goal(const DrillGuideModel& guide, const NailModel& nail, const RobotModel& robot,
                     const Eigen::Isometry3d& T_camera_guide, const Eigen::Isometry3d& T_camera_nail);

}  // namespace fluoro
