// fluoro demo --distal-locking: a generated view of the drill guide and the nail, the poses found
// from it, the robot's goal from a generated ROBOT.json, and the drilling error at that goal: the
// angle between each guide axis and its hole's true axis, and how far the true entry and exit
// points lie from the guide axis (the "what the robot would drill").
#include <Eigen/Geometry>
#include <chrono>
#include <cstdio>
#include <filesystem>

#include "apps/fluoro/demo_distal_locking.hpp"
#include "apps/fluoro/provenance.hpp"
#include "apps/fluoro/result_files.hpp"
#include "datasets/distal_locking_scene.hpp"
#include "engine/image_io.hpp"
#include "engine/json_io.hpp"
#include "engine/pose.hpp"
#include "pipelines/distal_locking/distal_locking.hpp"
#include "pipelines/distal_locking/robot_goal.hpp"

namespace fluoro::cli {
namespace {

double distance_to_line(const Eigen::Vector3d& x, const Eigen::Vector3d& p, const Eigen::Vector3d& d) {
  const Eigen::Vector3d u = d.normalized();
  return ((x - p) - (x - p).dot(u) * u).norm();
}

struct DrillError {
  double axis_deg = 0;        // guide axis at the goal against the hole's true axis
  double entry_exit_mm = 0;   // mean distance of the true entry and exit points from the guide axis
};

}  // namespace

void run_distal_locking_demo(const DistalLockingDemoOptions& o) {
  namespace fs = std::filesystem;
  make_output_directory(o.out_dir);
  const fs::path dir(o.out_dir);
  nlohmann::json summary;
  auto t = std::chrono::steady_clock::now();

  // 1. The view: a C-arm shot of the guide and the nail, tilted off the holes' axes, with the
  // calibration ring's balls as clutter, blur, quantum noise and two guide spheres hidden.
  DistalView view;
  view.pixels = o.pixels;
  view.tilt_deg = o.tilt_deg;
  DistalRendering rendering;
  rendering.blur_sigma_px = 0.5 * o.pixels / 512.0;
  rendering.photons_per_pixel = 20000;
  rendering.hidden_spheres = 2;
  rendering.seed = 5;
  const DistalScene scene = render_distal_scene(view, rendering);
  write_distal_scene(scene, (dir / "shot").string());
  // A robot whose base is somewhere in the world and whose tip now holds the guide where it is.
  RobotModel robot;
  robot.T_tip_guide = pose_from_rotation_vector(Eigen::Vector3d(0.0, 0.05, -0.1), Eigen::Vector3d(0, 10, 80));
  const Eigen::Isometry3d T_world_base =
      pose_from_rotation_vector(Eigen::Vector3d(0.3, -0.2, 0.1), Eigen::Vector3d(-120, 40, 500));
  robot.T_base_tip = T_world_base.inverse() * scene.T_world_guide * robot.T_tip_guide.inverse();
  write_json(robot_model_to_json(robot), (dir / "ROBOT.json").string());
  summary["timings_s"]["make_xray"] = seconds_since(t);

  // 2. What `fluoro distal-lock` does: the image as written, then both poses.
  t = std::chrono::steady_clock::now();
  const std::string image_path = (dir / "shot.png").string();
  const Image image = read_image(image_path);
  const NailMode mode = o.interactive ? NailMode::interactive : NailMode::generic;
  const DistalLocking r = locate_for_distal_locking(image, scene.camera, scene.guide, scene.nail, mode);
  summary["timings_s"]["locate"] = seconds_since(t);
  if (!r.ok) throw std::runtime_error("the demo's image could not be located: " + r.failure_reason);
  const RobotGoal goal = robot_goal(scene.guide, scene.nail, robot, r.T_camera_guide, r.T_camera_nail);

  // 3. Errors against the truth: the guide, the nail's hole axes, and the drill at the goal.
  const Eigen::Isometry3d guide_error = scene.T_world_guide.inverse() * r.T_world_guide;
  const double guide_rot_deg = rotation_angle_deg(guide_error);
  const double guide_trans_mm = (r.T_world_guide.translation() - scene.T_world_guide.translation()).norm();
  const Eigen::Vector3d true_z = scene.T_world_nail.linear().col(2);
  const double hole_axis_deg = axis_angle_deg(r.T_world_nail.linear().col(2), true_z);
  const Eigen::Isometry3d guide_at_goal = T_world_base * goal.T_base_goal * robot.T_tip_guide;
  const double radius = scene.nail.diameter_mm / 2;
  std::vector<DrillError> drill;
  for (size_t k = 0; k < scene.guide.axes.size() && k < scene.nail.holes.size(); ++k) {
    const Eigen::Vector3d p = guide_at_goal * scene.guide.axes[k].point_mm;
    const Eigen::Vector3d d = guide_at_goal.linear() * scene.guide.axes[k].direction;
    const Eigen::Vector3d c = scene.T_world_nail * scene.nail.holes[k].center_mm;
    DrillError e;
    e.axis_deg = axis_angle_deg(d, true_z);
    e.entry_exit_mm = 0.5 * (distance_to_line(c - radius * true_z, p, d) + distance_to_line(c + radius * true_z, p, d));
    drill.push_back(e);
  }

  summary["status"] = "ok";
  // No input files: the demo makes its X-ray and models in memory (and writes them for a rerun).
  summary["provenance"] = provenance("demo --distal-locking",
                                     {{"pixels", o.pixels}, {"tilt_deg", o.tilt_deg}, {"interactive", o.interactive}},
                                     nlohmann::json::array());
  summary["view"] = {{"pixels", o.pixels}, {"tilt_deg", o.tilt_deg}, {"mode", o.interactive ? "interactive" : "generic"}};
  summary["guide"] = {{"spheres_matched", r.guide.localisation.matched_ids.size()},
                      {"reprojection_rms_px", r.guide.localisation.rms_px},
                      {"rotation_error_deg", guide_rot_deg},
                      {"translation_error_mm", guide_trans_mm}};
  summary["nail"] = {{"hole_axis_error_deg", hole_axis_deg}};
  nlohmann::json holes = nlohmann::json::array();
  for (const DrillError& e : drill) holes.push_back({{"axis_error_deg", e.axis_deg}, {"entry_exit_error_mm", e.entry_exit_mm}});
  summary["drill_at_goal"] = holes;
  write_json(summary, (dir / "summary.json").string());

  std::printf("fluoro demo --distal-locking: %dx%d X-ray, hole axes %.1f deg off the ray through the nail, %s mode\n", o.pixels,
              o.pixels, o.tilt_deg, o.interactive ? "interactive" : "generic");
  std::printf("  guide:  %zu of %zu spheres matched (2 hidden), reprojection rms %.3f px; pose %.3f deg, %.2f mm off\n",
              r.guide.localisation.matched_ids.size(), scene.guide.spheres_mm.size(), r.guide.localisation.rms_px,
              guide_rot_deg, guide_trans_mm);
  std::printf("  nail:   hole axes %.3f deg off the truth\n", hole_axis_deg);
  for (size_t k = 0; k < drill.size(); ++k)
    std::printf("  drill %zu at the robot's goal: %.3f deg off the hole's axis, entry/exit %.3f mm off (mean)\n", k,
                drill[k].axis_deg, drill[k].entry_exit_mm);
  std::printf("  time:   %.3f s to locate both (render %.2f s)\n", summary["timings_s"]["locate"].get<double>(),
              summary["timings_s"]["make_xray"].get<double>());
  std::printf("  files:  %s/{shot.png, shot_camera.json, shot_guide.json, shot_nail.json, shot_truth.json, ROBOT.json, summary.json}\n",
              o.out_dir.c_str());
  const std::string p = o.out_dir + "/shot";
  std::printf("  again:  fluoro distal-lock --image %s.png --camera %s_camera.json --guide %s_guide.json --nail %s_nail.json "
              "--robot %s/ROBOT.json --out RESULT.json --overlay overlay.png\n",
              p.c_str(), p.c_str(), p.c_str(), p.c_str(), o.out_dir.c_str());
}

}  // namespace fluoro::cli
