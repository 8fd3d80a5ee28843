#include "pipelines/distal_locking/robot_goal.hpp"

#include <cmath>
#include <cstdio>
#include <limits>

#include "engine/error.hpp"
#include "engine/pose.hpp"

namespace fluoro {
namespace {

Eigen::Isometry3d frame(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& axis) {
  const Eigen::Vector3d z = axis.normalized();
  Eigen::Vector3d x = (b - a) - (b - a).dot(z) * z;
  x.normalize();
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() << x, z.cross(x), z;
  // The midpoint of the two axes, at the first axis' point level along z.
  const Eigen::Vector3d b_level = b - (b - a).dot(z) * z;
  T.translation() = 0.5 * (a + b_level);
  return T;
}

// The distance between the guide's two axes, across them.
double axes_spacing_mm(const DrillGuideModel& g) {
  const Eigen::Vector3d d = g.axes[0].direction.normalized();
  const Eigen::Vector3d sep = g.axes[1].point_mm - g.axes[0].point_mm;
  return (sep - sep.dot(d) * d).norm();
}

double holes_spacing_mm(const NailModel& n) { return (n.holes[1].center_mm - n.holes[0].center_mm).norm(); }

}  // namespace

Eigen::Isometry3d guide_axes_frame(const DrillGuideModel& g, const std::string& what) {
  if (g.axes.size() != 2) throw_input_error(what, "the robot's goal needs a guide with exactly two axes, it has " + std::to_string(g.axes.size()));
  const Eigen::Vector3d d0 = g.axes[0].direction, d1 = g.axes[1].direction;
  if (std::abs(d0.dot(d1)) < std::cos(0.5 * M_PI / 180)) throw_input_error(what, "the guide's two axes are not parallel");
  if (axes_spacing_mm(g) < 1.0) throw_input_error(what, "the guide's two axes coincide");
  return frame(g.axes[0].point_mm, g.axes[1].point_mm, d0);
}

Eigen::Isometry3d nail_holes_frame(const NailModel& n, const std::string& what) {
  if (n.holes.size() != 2) throw_input_error(what, "the robot's goal needs a nail with exactly two holes, it has " + std::to_string(n.holes.size()));
  return frame(n.holes[0].center_mm, n.holes[1].center_mm, Eigen::Vector3d::UnitZ());
}

RobotGoal robot_goal(const DrillGuideModel& guide, const NailModel& nail, const RobotModel& robot,
                     const Eigen::Isometry3d& T_camera_guide, const Eigen::Isometry3d& T_camera_nail) {
  const Eigen::Isometry3d A_g = guide_axes_frame(guide, "GUIDE.json"), A_h = nail_holes_frame(nail, "NAIL.json");
  // Where the robot's base is, seen through the guide it carries.
  const Eigen::Isometry3d T_camera_base = T_camera_guide * (robot.T_base_tip * robot.T_tip_guide).inverse();
  const Eigen::Isometry3d base_from_camera = T_camera_base.inverse();
  const Eigen::Matrix3d turns[4] = {Eigen::Matrix3d::Identity(), Eigen::Vector3d(-1, -1, 1).asDiagonal(),
                                    Eigen::Vector3d(1, -1, -1).asDiagonal(), Eigen::Vector3d(-1, 1, -1).asDiagonal()};
  RobotGoal best;
  double best_angle = std::numeric_limits<double>::infinity();
  for (const auto& S : turns) {
    Eigen::Isometry3d turn = Eigen::Isometry3d::Identity();
    turn.linear() = S;
    // The tip's goal with no slide; a slide s along the hole axes adds s * v to its translation.
    const Eigen::Isometry3d goal0 = base_from_camera * T_camera_nail * A_h * turn * A_g.inverse() * robot.T_tip_guide.inverse();
    const Eigen::Vector3d v = (base_from_camera * T_camera_nail * A_h).linear().col(2);
    const Eigen::Isometry3d delta = robot.T_base_tip.inverse() * goal0;
    const double angle = rotation_angle_deg(delta);
    if (angle >= best_angle - 1e-9) continue;
    best_angle = angle;
    const double s = -(goal0.translation() - robot.T_base_tip.translation()).dot(v);
    best.T_base_goal = goal0;
    best.T_base_goal.translation() += s * v;
    best.slide_mm = s;
    best.turn_from_now_deg = angle;
  }
  best.spacing_mismatch_mm = guide_nail_spacing_mismatch_mm(guide, nail);
  return best;
}

double guide_nail_spacing_mismatch_mm(const DrillGuideModel& guide, const NailModel& nail) {
  return axes_spacing_mm(guide) - holes_spacing_mm(nail);
}

void check_guide_fits_nail(const DrillGuideModel& guide, const NailModel& nail, const std::string& guide_what,
                           const std::string& nail_what) {
  guide_axes_frame(guide, guide_what);
  nail_holes_frame(nail, nail_what);
  const double axes = axes_spacing_mm(guide), holes = holes_spacing_mm(nail);
  if (std::abs(axes - holes) > kMaxSpacingMismatchMm) {
    char numbers[160];
    std::snprintf(numbers, sizeof numbers, "its two axes are %.3f mm apart and the holes %.3f mm (%.3f mm of difference, at most %.1f)",
                  axes, holes, std::abs(axes - holes), kMaxSpacingMismatchMm);
    throw_input_error(guide_what, std::string(numbers) + " in " + nail_what +
                                      ": no robot goal puts both axes on the holes (a guide for another nail?)");
  }
}

}  // namespace fluoro
