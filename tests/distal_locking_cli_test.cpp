// fluoro distal-lock end to end: RESULT.json's keys (shared/docs/FORMATS.md, "Distal locking") and
// values against the generated truth, the robot's goal, exit 2 with one line and no output on bad
// input, exit 3 with a "failed" result (the guide kept, no nail pose) when the nail is missing.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <string>

#include "datasets/distal_locking_scene.hpp"
#include "engine/json_io.hpp"
#include "engine/pose.hpp"
#include "tests/cli_fixture.hpp"

namespace fluoro {
namespace {

using nlohmann::json;

Eigen::Matrix4d matrix(const json& j) {
  Eigen::Matrix4d m;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) m(r, c) = j[size_t(r)][size_t(c)].get<double>();
  return m;
}

class DistalLockCli : public test::CliTest {
 protected:
  DistalScene write_scene(const DistalRendering& r, const DistalView& v = {}) {
    DistalScene s = render_distal_scene(v, r);
    write_distal_scene(s, path("s"));
    return s;
  }
  std::string args(const std::string& extra = "") const {
    return "distal-lock --image " + path("s.png") + " --camera " + path("s_camera.json") + " --guide " + path("s_guide.json") +
           " --nail " + path("s_nail.json") + " --out " + path("r.json") + " " + extra;
  }
};

TEST_F(DistalLockCli, ResultFileAgainstTruthWithRobotGoal) {
  DistalRendering r;
  r.blur_sigma_px = 0.5;
  DistalView v;
  v.tilt_deg = 7;
  const DistalScene s = write_scene(r, v);
  RobotModel robot;
  robot.T_tip_guide = pose_from_rotation_vector(Eigen::Vector3d(0.02, 0.0, -0.1), Eigen::Vector3d(0, 0, 90));
  robot.T_base_tip = pose_from_rotation_vector(Eigen::Vector3d(0.3, 0.1, 0.0), Eigen::Vector3d(100, 20, 400));
  write_json(robot_model_to_json(robot), path("robot.json"));
  const test::CliResult res = run(args("--robot " + path("robot.json") + " --overlay " + path("o.png")));
  ASSERT_EQ(res.code, 0) << res.err << res.out;
  const json doc = read_json(path("r.json"));
  EXPECT_EQ(doc["status"], "ok");
  expect_provenance(doc, "distal-lock");
  EXPECT_EQ(doc["provenance"]["settings"]["robot"], true);
  const Eigen::Isometry3d guide(matrix(doc["T_world_guide"])), nail(matrix(doc["T_world_nail"]));
  EXPECT_LT(rotation_angle_deg(s.T_world_guide.inverse() * guide), 0.3);
  EXPECT_LT((s.T_world_guide.translation() - guide.translation()).norm(), 0.5);
  EXPECT_LT(std::acos(std::min(1.0, nail.linear().col(2).dot(s.T_world_nail.linear().col(2)))) * 180 / M_PI, 0.5);
  ASSERT_EQ(doc["holes_world"].size(), 2u);
  for (size_t k = 0; k < 2; ++k) {
    const Eigen::Vector3d centre = s.T_world_nail * s.nail.holes[k].center_mm;
    for (const char* key : {"entry_mm", "exit_mm"}) {
      const Eigen::Vector3d p(doc["holes_world"][k][key][0], doc["holes_world"][k][key][1], doc["holes_world"][k][key][2]);
      EXPECT_NEAR((p - centre).norm(), 5.0, 1.0);
    }
  }
  EXPECT_GE(doc["guide_spheres_matched"]["count"].get<int>(), 20);
  EXPECT_EQ(doc["guide_spheres_matched"]["ids"].size(), doc["guide_spheres_matched"]["count"].get<size_t>());
  ASSERT_TRUE(doc.contains("T_base_goal"));
  EXPECT_TRUE(doc["timings_s"].contains("total"));
  EXPECT_TRUE(std::filesystem::exists(path("o.png")));
  // The goal puts the guide's first axis on the first hole's axis (the truth's).
  const Eigen::Isometry3d goal(matrix(doc["T_base_goal"]));
  const Eigen::Isometry3d T_world_base = s.T_world_guide * (robot.T_base_tip * robot.T_tip_guide).inverse();
  const Eigen::Isometry3d guide_at_goal = T_world_base * goal * robot.T_tip_guide;
  const Eigen::Vector3d p = guide_at_goal * s.guide.axes[0].point_mm, z = s.T_world_nail.linear().col(2);
  const Eigen::Vector3d c = s.T_world_nail * s.nail.holes[0].center_mm;
  EXPECT_LT(((p - c) - (p - c).dot(z) * z).norm(), 1.0);
}

TEST_F(DistalLockCli, TheInteractiveModeSaysWhetherItAcceptsTheView) {
  // Its pose assumes the hole axes along the ray through the nail: a 7-degree view is not one it
  // accepts, and the file and the output say so; the generated tilt-0 view is.
  for (const double tilt : {7.0, 0.0}) {
    SCOPED_TRACE(tilt);
    DistalRendering r;
    r.blur_sigma_px = 0.5;
    DistalView v;
    v.tilt_deg = tilt;
    write_scene(r, v);
    const test::CliResult res = run(args("--mode interactive"));
    ASSERT_EQ(res.code, 0) << res.err << res.out;
    const json doc = read_json(path("r.json"));
    EXPECT_EQ(doc["status"], "ok");
    ASSERT_TRUE(doc.contains("view"));
    EXPECT_EQ(doc["view"]["accepted_within_deg"].get<double>(), 1.0);
    EXPECT_EQ(doc["view"]["fronto_parallel"].get<bool>(), tilt == 0.0);
    EXPECT_NEAR(doc["view"]["deviation_deg"].get<double>(), tilt, 1.0);
    EXPECT_EQ(res.out.find("from fronto-parallel") != std::string::npos, tilt != 0.0) << res.out;
    // The image fit's quality, not the zeros of the fronto-parallel construction.
    EXPECT_GT(doc["nail_fit"]["rms"].get<double>(), 0.0);
    EXPECT_GT(doc["nail_fit"]["attenuation_per_mm"].get<double>(), 0.0);
  }
  // The generic mode's file has no such key.
  ASSERT_EQ(run(args()).code, 0);
  EXPECT_FALSE(read_json(path("r.json")).contains("view"));
}

TEST_F(DistalLockCli, NoNailIsFailedWithTheGuideKept) {
  DistalRendering r;
  r.nail_present = false;
  write_scene(r);
  const json doc = expect_failed(run(args()), "r.json", {"T_world_nail", "holes_world"});
  EXPECT_TRUE(doc.contains("T_world_guide"));
  EXPECT_NE(doc["reason"].get<std::string>().find("nail"), std::string::npos);
}

TEST_F(DistalLockCli, BadInputIsOneLineAndNoOutput) {
  DistalRendering r;
  r.supersampling = 1;
  write_scene(r);
  expect_bad_input(run(args("--mode sideways")), "--mode", "r.json");
  DrillGuideModel g = drill_guide_model();
  g.spheres_mm.resize(5);
  write_json(drill_guide_model_to_json(g), path("s_guide.json"));
  expect_bad_input(run(args()), "s_guide.json", "r.json");
  write_json(drill_guide_model_to_json(drill_guide_model()), path("s_guide.json"));
  NailModel n = nail_model();
  n.holes[0].center_mm.z() = 3;
  write_json(nail_model_to_json(n), path("s_nail.json"));
  expect_bad_input(run(args()), "s_nail.json", "r.json");
  write_json(nail_model_to_json(nail_model()), path("s_nail.json"));
  // A guide whose axes are 6 mm further apart than the holes: no goal puts both drills through
  // (the goal would share their midline, each drill 3 mm off its 5 mm hole's centre).
  RobotModel robot;
  write_json(robot_model_to_json(robot), path("robot.json"));
  g = drill_guide_model();
  ASSERT_EQ(g.axes.size(), 2u);
  const Eigen::Vector3d along = g.axes[0].direction.normalized(), sep = g.axes[1].point_mm - g.axes[0].point_mm;
  const Eigen::Vector3d across = (sep - sep.dot(along) * along).normalized();
  g.axes[1].point_mm += 6.0 * across;
  write_json(drill_guide_model_to_json(g), path("s_guide.json"));
  const test::CliResult wide = run(args("--robot " + path("robot.json")));
  expect_bad_input(wide, "s_guide.json", "r.json");
  EXPECT_NE(wide.err.find("no robot goal puts both axes on the holes"), std::string::npos) << wide.err;
  EXPECT_NE(wide.err.find("(6.000 mm of difference, at most 0.5)"), std::string::npos) << wide.err;
  // Within 0.5 mm it is the robot's goal, with the mismatch reported.
  g.axes[1].point_mm -= 5.7 * across;
  write_json(drill_guide_model_to_json(g), path("s_guide.json"));
  ASSERT_EQ(run(args("--robot " + path("robot.json"))).code, 0);
  EXPECT_NEAR(read_json(path("r.json"))["robot"]["spacing_mismatch_mm"].get<double>(), 0.3, 1e-6);
  std::filesystem::remove(path("r.json"));
  write_json(drill_guide_model_to_json(drill_guide_model()), path("s_guide.json"));
  write_text("s.png", "not a png");
  expect_bad_input(run(args()), "s.png", "r.json");
}

}  // namespace
}  // namespace fluoro

namespace fluoro {
namespace {

// fluoro demo --distal-locking: what the robot would drill at the goal it computes, against the
// generated truth (the goals: 0.5 deg, 1.0 mm), and the files for the real command.
TEST_F(DistalLockCli, DemoDrillsOnTheHoleAxes) {
  const test::CliResult r = run("demo --distal-locking --pixels 512 --tilt 10 --out-dir " + path("demo"));
  ASSERT_EQ(r.code, 0) << r.err << r.out;
  const json s = read_json(path("demo/summary.json"));
  EXPECT_EQ(s["status"], "ok");
  EXPECT_GE(s["guide"]["spheres_matched"].get<int>(), 20);
  EXPECT_LT(s["guide"]["rotation_error_deg"].get<double>(), 0.3);
  ASSERT_EQ(s["drill_at_goal"].size(), 2u);
  for (const json& hole : s["drill_at_goal"]) {
    EXPECT_LT(hole["axis_error_deg"].get<double>(), 0.5);
    EXPECT_LT(hole["entry_exit_error_mm"].get<double>(), 1.0);
  }
  for (const char* f : {"shot.png", "shot_camera.json", "shot_guide.json", "shot_nail.json", "ROBOT.json"})
    EXPECT_TRUE(std::filesystem::exists(path(std::string("demo/") + f))) << f;
  // A demo for two things at once is refused.
  EXPECT_EQ(run("demo --distal-locking --calibration --out-dir " + path("x")).code, 2);
}

}  // namespace
}  // namespace fluoro
