#pragma once
// The distal-locking model files (shared/docs/FORMATS.md, "Distal locking"): the robot-mounted drill
// guide (GUIDE.json), the intramedullary nail with its locking holes (NAIL.json) and the robot's
// current and mounting transforms (ROBOT.json).
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace fluoro {

// A drill axis of the guide: a point on it and its unit direction, in the guide's frame.
struct GuideAxis {
  std::string name;
  Eigen::Vector3d point_mm;
  Eigen::Vector3d direction;
};

struct DrillGuideModel {
  double sphere_diameter_mm = 3.0;
  std::vector<Eigen::Vector3d> spheres_mm;
  std::vector<GuideAxis> axes;
};

// The nail's frame: long axis x, hole axes along z, the centre at the origin. Every hole's centre
// lies on the nail's long axis (y = z = 0) and its axis is the nail's z.
struct NailHole {
  Eigen::Vector3d center_mm;
  double diameter_mm = 5.0;
};
struct NailModel {
  double diameter_mm = 10.0;
  std::vector<NailHole> holes;
};

struct RobotModel {
  Eigen::Isometry3d T_base_tip = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_tip_guide = Eigen::Isometry3d::Identity();
};

// Throws InputError naming the path for a missing file, bad JSON, a wrong "kind", non-finite
// numbers, fewer than 6 spheres, all spheres in one plane, or an axis with a zero direction.
DrillGuideModel read_drill_guide_model(const std::string& path);
nlohmann::json drill_guide_model_to_json(const DrillGuideModel& guide);

// Throws InputError for a missing file, bad JSON, a wrong "kind", no hole, a hole whose centre is
// not on the nail's long axis (|y|, |z| > 0.01 mm), a hole not narrower than the nail, or two holes
// that overlap.
NailModel read_nail_model(const std::string& path);
nlohmann::json nail_model_to_json(const NailModel& nail);

// Throws InputError for a missing file, bad JSON or a matrix that is not a proper rigid transform.
RobotModel read_robot_model(const std::string& path);
nlohmann::json robot_model_to_json(const RobotModel& robot);

}  // namespace fluoro
