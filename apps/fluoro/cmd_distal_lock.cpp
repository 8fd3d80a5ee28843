// fluoro distal-lock: the drill guide's and the nail's poses from one X-ray, where each locking
// hole's axis enters and leaves the nail, and with --robot the robot's goal pose
// (shared/docs/FORMATS.md, "Distal locking"; docs/distal_locking.md).
#include <cstdio>
#include <string>

#include "apps/fluoro/commands.hpp"
#include "apps/fluoro/global_options.hpp"
#include "apps/fluoro/provenance.hpp"
#include "apps/fluoro/result_files.hpp"
#include "engine/distal_locking_models.hpp"
#include "engine/error.hpp"
#include "engine/image_io.hpp"
#include "engine/json_io.hpp"
#include "pipelines/distal_locking/distal_locking.hpp"
#include "pipelines/distal_locking/distal_locking_overlay.hpp"
#include "pipelines/distal_locking/robot_goal.hpp"

namespace fluoro::cli {
namespace {

struct DistalLockOptions {
  std::string image, camera, guide, nail, mode = "generic", robot, out, overlay;
};

nlohmann::json matrix(const Eigen::Matrix4d& m) {
  nlohmann::json rows = nlohmann::json::array();
  for (int r = 0; r < 4; ++r) rows.push_back({m(r, 0), m(r, 1), m(r, 2), m(r, 3)});
  return rows;
}
nlohmann::json vec(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

void run(const DistalLockOptions& o) {
  StageTimer timer;
  check_output_path(o.out);
  if (!o.overlay.empty()) check_output_path(o.overlay);
  if (o.mode != "generic" && o.mode != "interactive")
    throw_input_error("--mode", "must be generic or interactive, not " + o.mode);
  const NailMode mode = o.mode == "interactive" ? NailMode::interactive : NailMode::generic;
  const PinholeCamera camera = read_camera(o.camera);
  const DrillGuideModel guide = read_drill_guide_model(o.guide);
  const NailModel nail = read_nail_model(o.nail);
  std::optional<RobotModel> robot;
  if (!o.robot.empty()) {
    robot = read_robot_model(o.robot);
    // The chain needs two parallel axes and two holes, spaced alike.
    check_guide_fits_nail(guide, nail, o.guide, o.nail);
  }
  const Image image = read_image(o.image);
  if (image.width != camera.width || image.height != camera.height)
    throw_input_error(o.image, "is " + std::to_string(image.width) + "x" + std::to_string(image.height) + ", the camera " +
                                   o.camera + " describes " + std::to_string(camera.width) + "x" + std::to_string(camera.height) +
                                   " images");
  timer.lap("read");

  const DistalLocking r = locate_for_distal_locking(image, camera, guide, nail, mode);
  nlohmann::json doc;
  doc["status"] = r.ok ? "ok" : "failed";
  if (!r.ok) doc["reason"] = r.failure_reason;
  doc["mode"] = o.mode;
  const auto& loc = r.guide.localisation;
  doc["guide_spheres_matched"] = {{"count", loc.ok ? loc.matched_ids.size() : 0},
                                  {"ids", loc.ok ? nlohmann::json(loc.matched_ids) : nlohmann::json::array()}};
  doc["guide_spheres_found"] = r.guide.circles.size();
  if (r.guide_ok) {
    doc["T_world_guide"] = matrix(r.T_world_guide.matrix());
    doc["guide_reprojection_px"] = {{"rms", loc.rms_px}, {"max", loc.max_px}};
  }
  if (r.nail_detection.ok) {
    nlohmann::json holes = nlohmann::json::array();
    for (const auto& h : r.nail_detection.holes)
      holes.push_back({{"centre_px", {h.centre_px.x(), h.centre_px.y()}}, {"major_px", h.major_px}, {"minor_px", h.minor_px},
                       {"angle_deg", h.angle_deg}});
    doc["nail_image"] = {{"band_width_px", r.nail_detection.band.width_px}, {"hole_ellipses", holes}};
  }
  timer.lap("locate");
  if (r.ok) {
    doc["T_world_nail"] = matrix(r.T_world_nail.matrix());
    nlohmann::json holes = nlohmann::json::array();
    for (const auto& h : r.holes) {
      nlohmann::json j = {{"entry_mm", vec(h.entry_mm)}, {"exit_mm", vec(h.exit_mm)}};
      if (mode == NailMode::interactive) j["circularity"] = h.circularity, j["deviation_deg"] = h.deviation_deg;
      holes.push_back(j);
    }
    doc["holes_world"] = holes;
    // The interactive pose assumes the hole axes lie along the ray through the nail: on a view the
    // generic fit finds further off, its axes are off by that much (docs/distal_locking.md). The
    // result says so in the file a robot's software reads, not only in the technician's scores.
    if (mode == NailMode::interactive)
      doc["view"] = {{"fronto_parallel", r.fronto_parallel},
                     {"deviation_deg", r.view_deviation_deg},
                     {"accepted_within_deg", kFrontoParallelDeg}};
    doc["nail_fit"] = {{"rms", r.nail_pose.rms}, {"mirror_rms", r.nail_pose.mirror_rms}, {"blur_px", r.nail_pose.blur_px},
                       {"attenuation_per_mm", r.nail_pose.attenuation_per_mm},
                       {"tie_spread_deg", r.nail_pose.tie_spread_deg}};
    if (robot) {
      const RobotGoal goal = robot_goal(guide, nail, *robot, r.T_camera_guide, r.T_camera_nail);
      doc["T_base_goal"] = matrix(goal.T_base_goal.matrix());
      doc["robot"] = {{"slide_mm", goal.slide_mm}, {"turn_from_now_deg", goal.turn_from_now_deg},
                      {"spacing_mismatch_mm", goal.spacing_mismatch_mm}};
      timer.lap("robot");
    }
  }
  if (!o.overlay.empty()) {
    const auto rgb = distal_locking_overlay(image, camera, guide, nail, r);
    write_png_u8(rgb, image.width, image.height, 3, o.overlay);
    timer.lap("overlay");
  }
  doc["inputs"] = {{"image", file_digest(o.image)}, {"camera", file_digest(o.camera)}, {"guide", file_digest(o.guide)},
                   {"nail", file_digest(o.nail)}};
  if (robot) doc["inputs"]["robot"] = file_digest(o.robot);
  doc["provenance"] = provenance("distal-lock", {{"mode", o.mode}, {"robot", robot.has_value()}, {"overlay", !o.overlay.empty()}},
                                 doc["inputs"]);
  doc["timings_s"] = timer.json();
  doc["timings_s"]["spheres"] = r.spheres_seconds;
  doc["timings_s"]["nail_detection"] = r.nail_detection_seconds;
  doc["timings_s"]["nail_pose"] = r.nail_pose_seconds;
  doc["timings_s"]["total"] = timer.total();
  write_json(doc, o.out);
  if (!r.ok) throw MethodFailed(o.out + ": distal locking failed: " + r.failure_reason);
  std::printf("%s: %zu guide spheres matched (rms %.3f px), nail %s mode, %.3f s\n", o.out.c_str(), loc.matched_ids.size(),
              loc.rms_px, o.mode.c_str(), timer.total());
  if (mode == NailMode::interactive && !r.fronto_parallel)
    std::printf("%s: the view is %.1f degrees from fronto-parallel (accepted within %.1f): the interactive pose's hole "
                "axes are off by about that much; turn the C-arm until the holes are round, or use --mode generic\n",
                o.out.c_str(), r.view_deviation_deg, kFrontoParallelDeg);
}

}  // namespace

void add_distal_lock_command(CLI::App& app) {
  auto o = std::make_shared<DistalLockOptions>();
  auto* cmd = app.add_subcommand("distal-lock", "Drill guide and nail poses from one X-ray, the locking holes' entry and exit "
                                                "points, and the robot's goal pose");
  cmd->add_option("--image", o->image, "X-ray (log domain: metal dark) showing the drill guide and the nail")->required();
  cmd->add_option("--camera", o->camera, "CAMERA.json of the view (fluoro calibrate)")->required();
  cmd->add_option("--guide", o->guide, "GUIDE.json: the drill guide's spheres and axes")->required();
  cmd->add_option("--nail", o->nail, "NAIL.json: the nail's diameter and holes")->required();
  cmd->add_option("--mode", o->mode, "generic (one image, any view) | interactive (fronto-parallel view, the seed's)")
      ->capture_default_str();
  cmd->add_option("--robot", o->robot, "ROBOT.json: T_base_tip and T_tip_guide; adds T_base_goal");
  cmd->add_option("--out", o->out, "RESULT.json")->required();
  cmd->add_option("--overlay", o->overlay, "PNG: matched spheres with their ids, the nail band, the hole ellipses, the guide axes");
  cmd->callback([o] { run(*o); });
}

}  // namespace fluoro::cli
