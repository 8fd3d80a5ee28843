// Distal locking against the scene generator's truth: the ray-cylinder chords against closed forms,
// the model files' checks, the guide's spheres and pose, the nail's pose in both modes, the entry
// and exit points, and the robot chain against its defining property.
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <cmath>

#include "datasets/distal_locking_scene.hpp"
#include "datasets/calibration_phantom.hpp"
#include "engine/error.hpp"
#include "engine/json_io.hpp"
#include "engine/nail_chord.hpp"
#include "engine/pose.hpp"
#include "pipelines/distal_locking/distal_locking.hpp"
#include "pipelines/distal_locking/nail_bitangent_pose.hpp"
#include "pipelines/distal_locking/robot_goal.hpp"

namespace fluoro {
namespace {



struct Rendered {
  DistalScene scene;
  Image xray;
};
Rendered render(const DistalView& v, const DistalRendering& r) {
  Rendered out{render_distal_scene(v, r), {}};
  out.xray = log_domain_xray(out.scene.line_integral);
  return out;
}

// 2 x 2 rays per pixel keep the tests fast; the blur hides the difference from 3 x 3.
DistalRendering clean() {
  DistalRendering r;
  r.blur_sigma_px = 0.5;
  r.supersampling = 2;
  return r;
}

TEST(RayCylinder, ChordsMatchClosedForms) {
  // A ray along z through a cylinder along x of radius 5 at depth 100, offset 3 from the axis.
  const Cylinder c{Eigen::Vector3d(0, 3, 100), Eigen::Vector3d::UnitX(), 5.0};
  EXPECT_NEAR(ray_in_cylinder(c, Eigen::Vector3d::UnitZ()).length(), 2 * std::sqrt(25.0 - 9.0), 1e-12);
  EXPECT_NEAR(ray_in_cylinder(c, Eigen::Vector3d::UnitZ()).lo, 100 - 4.0, 1e-12);
  // A finite cylinder is cut by its end planes; a ray that misses has no chord.
  const Cylinder end{Eigen::Vector3d(0, 0, 100), Eigen::Vector3d::UnitX(), 5.0, 1.0, 50.0};
  EXPECT_EQ(ray_in_cylinder(end, Eigen::Vector3d::UnitZ()).length(), 0.0);
  EXPECT_EQ(ray_in_cylinder({Eigen::Vector3d(0, 6, 100), Eigen::Vector3d::UnitX(), 5.0}, Eigen::Vector3d::UnitZ()).length(), 0.0);
  // The nail along its hole's axis: no metal through the hole's middle; the full rod beside it;
  // a ray 2 mm off the hole's axis (inside the 2.5 mm hole) also crosses no metal.
  const NailModel nail = nail_model();
  const PlacedNail n = place_nail(nail, Eigen::Matrix3d::Identity(), Eigen::Vector3d(15, 0, 500));
  EXPECT_NEAR(nail_chord_mm(n, Eigen::Vector3d(0, 0, 1)), 0.0, 1e-9);
  EXPECT_NEAR(nail_chord_mm(n, Eigen::Vector3d(15, 0, 500).normalized()), 10.0, 1e-2);
  const Eigen::Vector3d beside = Eigen::Vector3d(2.0, 0, 500).normalized();
  EXPECT_NEAR(nail_chord_mm(n, beside), 0.0, 0.05);  // the ray is 1/250 off the axis: it grazes the wall
}

TEST(RayCylinder, ChordGradientMatchesFiniteDifferences) {
  // The nail fit's analytic Jacobian: the chord's derivative with respect to turning the nail about
  // its origin and moving it, against central differences of the exact chord, for rays across the
  // rod and both holes of a tilted nail. Rays within reach of a kink (an interval endpoint changing
  // cylinder, or a grazing ray) are told by their one-sided differences disagreeing and skipped.
  const NailModel nail = nail_model();
  const Eigen::Matrix3d R = (Eigen::AngleAxisd(0.2, Eigen::Vector3d(0.3, 1, 0.2).normalized()) *
                             Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitZ())).toRotationMatrix();
  const Eigen::Vector3d t(6, -4, 700);
  const PlacedNail placed = place_nail(nail, R, t);
  const double h = 1e-6;
  int compared = 0, rays = 0;
  double worst = 0;
  for (double x = -30; x <= 30; x += 0.37)
    for (double y = -8; y <= 8; y += 0.41) {
      const Eigen::Vector3d d = (t + R * Eigen::Vector3d(x, y, 0)).normalized();
      Eigen::Matrix<double, 6, 1> g;
      const double c = nail_chord_gradient(placed, d, &g, 1e9);  // uncapped: the exact derivative
      ASSERT_NEAR(c, nail_chord_mm(placed, d), 1e-12);
      if (c <= 0) continue;
      ++rays;
      for (int k = 0; k < 6; ++k) {
        Eigen::Vector3d w = Eigen::Vector3d::Zero(), v = Eigen::Vector3d::Zero();
        (k < 3 ? w : v)(k % 3) = h;
        const auto chord = [&](double s) {
          const Eigen::Matrix3d Rs = Eigen::AngleAxisd(s * w.norm(), w.norm() > 0 ? w.normalized() : Eigen::Vector3d::UnitX()).toRotationMatrix() * R;
          return nail_chord_mm(place_nail(nail, Rs, t + s * v), d);
        };
        const double c0 = chord(0), plus = (chord(1) - c0) / h, minus = (c0 - chord(-1)) / h;
        if (std::abs(plus - minus) > 1e-3 * (1 + std::abs(plus))) continue;  // a kink within h
        ++compared;
        const double e = std::abs(g(k) - 0.5 * (plus + minus)) / (1 + std::abs(plus));
        worst = std::max(worst, e);
      }
    }
  EXPECT_GT(rays, 500);
  EXPECT_GT(compared, 6 * rays * 9 / 10);
  EXPECT_LT(worst, 1e-3);
}

TEST(DistalModels, RejectBadFiles) {
  const std::string dir = testing::TempDir();
  DrillGuideModel g = drill_guide_model();
  g.spheres_mm.resize(5);
  write_json(drill_guide_model_to_json(g), dir + "/g5.json");
  EXPECT_THROW(read_drill_guide_model(dir + "/g5.json"), InputError);
  NailModel n = nail_model();
  n.holes[1].center_mm.y() = 2.0;
  write_json(nail_model_to_json(n), dir + "/n_off.json");
  EXPECT_THROW(read_nail_model(dir + "/n_off.json"), InputError);
  write_json(nail_model_to_json(nail_model()), dir + "/n.json");
  EXPECT_EQ(read_nail_model(dir + "/n.json").holes.size(), 2u);
}

TEST(DistalGuide, SpheresPairedAndPoseAgainstTruth) {
  const Rendered s = render({}, clean());
  const GuideDetection g = localise_guide(s.xray, s.scene.guide, s.scene.camera.K);
  ASSERT_TRUE(g.localisation.ok) << g.localisation.failure_reason;
  const Eigen::Isometry3d truth = s.scene.camera.camera_from_world() * s.scene.T_world_guide;
  EXPECT_GE(g.localisation.matched_ids.size(), 22u);
  std::vector<double> isolated;
  for (int id : g.localisation.matched_ids) {
    const auto& c = g.circles[size_t(g.localisation.detection_of[size_t(id)])];
    const double err = (project_pose(s.scene.camera.K, truth, s.scene.guide.spheres_mm[size_t(id)]) - c.centre_px).norm();
    EXPECT_LT(err, 2.0) << "sphere " << id << " paired with the wrong detection";
    if (!c.crowded) isolated.push_back(err);
  }
  std::sort(isolated.begin(), isolated.end());
  // Spheres clear of the nail's edges and of each other: within 0.1 px of the truth.
  EXPECT_LT(isolated[isolated.size() / 2], 0.05);
  const Eigen::Isometry3d e = truth.inverse() * g.localisation.T_camera_guide;
  EXPECT_LT(rotation_angle_deg(e), 0.3);
  EXPECT_LT(e.translation().norm(), 0.5);
}

TEST(DistalGuide, EightHiddenSpheresStillPairedCorrectly) {
  DistalRendering r = clean();
  r.hidden_spheres = 8;
  r.seed = 5;
  DistalView v;
  v.tilt_deg = 6;
  const Rendered s = render(v, r);
  const GuideDetection g = localise_guide(s.xray, s.scene.guide, s.scene.camera.K);
  ASSERT_TRUE(g.localisation.ok) << g.localisation.failure_reason;
  const Eigen::Isometry3d truth = s.scene.camera.camera_from_world() * s.scene.T_world_guide;
  for (int id : g.localisation.matched_ids) {
    EXPECT_FALSE(std::binary_search(s.scene.hidden_ids.begin(), s.scene.hidden_ids.end(), id)) << id;
    const auto& c = g.circles[size_t(g.localisation.detection_of[size_t(id)])];
    EXPECT_LT((project_pose(s.scene.camera.K, truth, s.scene.guide.spheres_mm[size_t(id)]) - c.centre_px).norm(), 2.0);
  }
  EXPECT_LT(rotation_angle_deg(truth.inverse() * g.localisation.T_camera_guide), 0.5);
}

// What the robot would drill: the hole axes and the entry and exit points against the truth.
void expect_holes_near_truth(const DistalLocking& r, const DistalScene& s, double max_angle_deg, double max_mm) {
  ASSERT_TRUE(r.ok) << r.failure_reason;
  ASSERT_EQ(r.holes.size(), s.nail.holes.size());
  EXPECT_LT(axis_angle_deg(r.T_world_nail.linear().col(2), s.T_world_nail.linear().col(2)), max_angle_deg);
  const Eigen::Vector3d guide_centre = s.T_world_guide * Eigen::Vector3d(0, 0, 10);
  for (size_t k = 0; k < s.nail.holes.size(); ++k) {
    const Eigen::Vector3d a = s.T_world_nail * (s.nail.holes[k].center_mm - Eigen::Vector3d(0, 0, 5));
    const Eigen::Vector3d b = s.T_world_nail * (s.nail.holes[k].center_mm + Eigen::Vector3d(0, 0, 5));
    const bool a_entry = (a - guide_centre).norm() < (b - guide_centre).norm();
    EXPECT_LT((r.holes[k].entry_mm - (a_entry ? a : b)).norm(), max_mm) << "hole " << k;
    EXPECT_LT((r.holes[k].exit_mm - (a_entry ? b : a)).norm(), max_mm) << "hole " << k;
  }
}

TEST(DistalNail, GenericModeTiltedViewAgainstTruth) {
  DistalView v;
  v.tilt_deg = 10;
  v.tilt_azimuth_deg = 60;
  const Rendered s = render(v, clean());
  const DistalLocking r = locate_for_distal_locking(s.xray, s.scene.camera, s.scene.guide, s.scene.nail, NailMode::generic);
  expect_holes_near_truth(r, s.scene, 0.5, 1.0);
}

// Image 63 of the big sweep (bench/distal_locking_bench.cpp --big-sweep 24 512: tilt 3 degrees,
// 5000 photons, 7 guide spheres hidden): two fits 3.4 degrees apart explain the image alike, and
// the guide (2.8 degrees misaligned) chose the one 3.6 degrees off the truth. Generic mode flags
// it instead of reporting a guess; the interactive mode, whose axes are the rays, still reports.
TEST(DistalNail, GenericModeFlagsATieTheGuideCannotDecide) {
  DistalView v;
  v.pixels = 512;
  v.tilt_deg = 3;
  v.tilt_azimuth_deg = 214.56637652708429;
  v.nail_roll_deg = 56.228251784927807;
  v.nail_depth_mm = 760.24651729851155;
  v.nail_offset_mm = Eigen::Vector2d(-12.02727402753316, 1.6349157830668304);
  v.guide_gap_mm = 50.716087902192733;
  v.guide_misalignment_deg = 2.8442417036444096;
  v.guide_offset_mm = Eigen::Vector3d(1.0714102131266632, 2.2925386234110174, 0);
  DistalRendering r;
  r.blur_sigma_px = 0.6735332624004351;
  r.photons_per_pixel = 5000;
  r.hidden_spheres = 7;
  r.seed = 6502755475689508157ull;
  const Rendered s = render(v, r);
  const DistalLocking g = locate_for_distal_locking(s.xray, s.scene.camera, s.scene.guide, s.scene.nail, NailMode::generic);
  EXPECT_FALSE(g.ok);
  EXPECT_TRUE(g.guide_ok) << g.failure_reason;  // the guide's pose stands
  EXPECT_NE(g.failure_reason.find("nail pose ambiguous"), std::string::npos) << g.failure_reason;
  EXPECT_GT(g.nail_pose.tie_spread_deg, 3.0);
  const DistalLocking i = locate_for_distal_locking(s.xray, s.scene.camera, s.scene.guide, s.scene.nail, NailMode::interactive);
  ASSERT_TRUE(i.ok) << i.failure_reason;
  EXPECT_NEAR(i.nail_pose.tie_spread_deg, g.nail_pose.tie_spread_deg, 1e-9);  // the same image fit
}

TEST(DistalNail, InteractiveModeScoresGuideTowardsFrontoParallel) {
  DistalView v;
  v.tilt_deg = 12;
  v.tilt_azimuth_deg = 90;  // about the nail's y: the lens shortens along the nail
  const Rendered tilted = render(v, clean());
  const DistalLocking a =
      locate_for_distal_locking(tilted.xray, tilted.scene.camera, tilted.scene.guide, tilted.scene.nail, NailMode::interactive);
  ASSERT_TRUE(a.ok) << a.failure_reason;
  // Fronto-parallel with the nail well off the image's centre (its ray 1.9 degrees off the central
  // ray): the view the technician is guided to is along the ray through the nail.
  v.tilt_deg = 0;
  v.nail_offset_mm = Eigen::Vector2d(18, -14);
  const Rendered straight = render(v, clean());
  const DistalLocking b =
      locate_for_distal_locking(straight.xray, straight.scene.camera, straight.scene.guide, straight.scene.nail, NailMode::interactive);
  ASSERT_TRUE(b.ok) << b.failure_reason;
  const auto true_deviation = [](const DistalScene& s, size_t k) {
    const Eigen::Vector3d c = s.T_world_nail * s.nail.holes[k].center_mm;
    return axis_angle_deg(c - s.camera.source(), s.T_world_nail.linear().col(2));
  };
  for (size_t k = 0; k < 2; ++k) {
    // Tilted 12 degrees along the nail, the lens is two 5 mm circles 10 tan 12 = 2.1 mm apart:
    // 2.9 mm long, 4.5 mm wide (0.64; 0.6 to 0.67 for the holes' 11 to 13 degrees off their rays),
    // read at 512^2 as 6 by 11 pixels, the outline's pixels making it rounder.
    EXPECT_GT(b.holes[k].circularity, 0.9);
    EXPECT_LT(a.holes[k].circularity, 0.85);
    // Near a fronto-parallel view the tilt is less sure (docs/distal_locking.md: 0.5 degrees
    // mean at tilt 0, under 1 degree).
    EXPECT_NEAR(b.holes[k].deviation_deg, true_deviation(straight.scene, k), 1.0);
    EXPECT_NEAR(a.holes[k].deviation_deg, true_deviation(tilted.scene, k), 0.5);
  }
  // In the fronto-parallel view the seed's pose: the axes along the ray through the nail's centre,
  // at the depth of the cylinder fit. The holes' outline diameters put it 39 mm off here; the fit's
  // depth is 2.3-2.4 mm off on the noise-free default view (the generic mode's own, the same before
  // the analytic Jacobian: docs/distal_locking.md), hence 3 mm. The axes: within 0.1 degrees (an
  // axis along the central ray would be 1.9 off; each hole's depth from the fit turned it 0.1-0.4).
  EXPECT_TRUE(b.fronto_parallel) << b.view_deviation_deg;
  EXPECT_FALSE(a.fronto_parallel) << a.view_deviation_deg;
  EXPECT_LT(axis_angle_deg(b.T_world_nail.linear().col(2), straight.scene.T_world_nail.linear().col(2)), 0.1);
  expect_holes_near_truth(b, straight.scene, 2.0, 3.0);
}

TEST(DistalNail, HoleAxesFarFromTheGuideAreFlaggedNotReported) {
  // The guide 25 degrees off the holes: the fit starts along it and along the ray; whichever
  // minimum it reaches, hole axes over 15 degrees from the guide's are not reported.
  DistalView v;
  v.tilt_deg = 8;
  v.guide_misalignment_deg = 25;
  const Rendered s = render(v, clean());
  const DistalLocking r = locate_for_distal_locking(s.xray, s.scene.camera, s.scene.guide, s.scene.nail, NailMode::generic);
  ASSERT_TRUE(r.guide_ok) << r.failure_reason;
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.failure_reason.find("not resolved"), std::string::npos) << r.failure_reason;
}


TEST(DistalNail, BitangentPoseRecoversAPlanarNailFromItsHoleEllipses) {
  // The seed's planar pose from exact data: the nail's hole circles (mid-plane, z = 0) projected as
  // conics under a tilted pose, their ellipses' parameters, the four outer bitangent points, IPPE.
  const NailModel nail = nail_model();
  const Eigen::Matrix3d K = (Eigen::Matrix3d() << 1700, 0, 256, 0, 1700, 256, 0, 0, 1).finished();
  CameraPose T = CameraPose::Identity();
  T.linear() = (Eigen::AngleAxisd(0.15, Eigen::Vector3d(0.6, 0.8, 0)) * Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ())).toRotationMatrix();
  T.translation() = Eigen::Vector3d(5, -3, 700);
  Eigen::Matrix3d H;
  H << T.linear().col(0), T.linear().col(1), T.translation();
  H = K * H;
  NailDetection det;
  for (const auto& h : nail.holes) {
    const double r = 0.5 * h.diameter_mm, cx = h.center_mm.x();
    Eigen::Matrix3d C;  // (x - cx)^2 + y^2 - r^2 = 0
    C << 1, 0, -cx, 0, 1, 0, -cx, 0, cx * cx - r * r;
    Eigen::Matrix3d Ci = H.inverse().transpose() * C * H.inverse();
    Ci /= -Ci(2, 2) + Ci.block<1, 2>(2, 0) * Ci.topLeftCorner<2, 2>().inverse() * Ci.block<2, 1>(0, 2);
    const Eigen::Matrix2d A = Ci.topLeftCorner<2, 2>();
    HoleEllipse e;
    e.centre_px = -A.inverse() * Ci.block<2, 1>(0, 2);
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(A);  // (x-c)^T A (x-c) = 1
    e.major_px = 2 / std::sqrt(es.eigenvalues()(0));
    e.minor_px = 2 / std::sqrt(es.eigenvalues()(1));
    e.angle_deg = std::atan2(es.eigenvectors()(1, 0), es.eigenvectors()(0, 0)) * 180 / 3.14159265358979;
    det.holes.push_back(e);
  }
  det.ok = true;
  // The guide along the truth, so that the symmetric poses resolve to it.
  const NailPoseEstimate p = bitangent_nail_pose(det, nail, K, T.linear().col(0), T.linear().col(2));
  ASSERT_TRUE(p.ok) << p.failure_reason;
  EXPECT_LT(rotation_angle_deg(T.inverse() * p.T_camera_nail), 0.05);
  EXPECT_LT((T.translation() - p.T_camera_nail.translation()).norm(), 0.05);
}

TEST(DistalNail, NoNailFailsButKeepsTheGuide) {
  DistalRendering r = clean();
  r.nail_present = false;
  const Rendered s = render({}, r);
  const DistalLocking out = locate_for_distal_locking(s.xray, s.scene.camera, s.scene.guide, s.scene.nail, NailMode::generic);
  EXPECT_FALSE(out.ok);
  EXPECT_TRUE(out.guide_ok);
  EXPECT_FALSE(out.nail_ok);
  EXPECT_FALSE(out.failure_reason.empty());
}

TEST(RobotGoal, PutsGuideAxesOnHoleAxesNearestTheCurrentPose) {
  const DrillGuideModel guide = drill_guide_model();
  const NailModel nail = nail_model();
  RobotModel robot;
  robot.T_base_tip = pose_from_rotation_vector(Eigen::Vector3d(0.1, -0.2, 0.3), Eigen::Vector3d(200, -50, 300));
  robot.T_tip_guide = pose_from_rotation_vector(Eigen::Vector3d(0.0, 0.05, -0.1), Eigen::Vector3d(0, 10, 80));
  const Eigen::Isometry3d T_camera_guide = pose_from_rotation_vector(Eigen::Vector3d(0.05, 0.02, 0.3), Eigen::Vector3d(5, -2, 650));
  // The nail: the guide's axes turned by 4 degrees and shifted, 60 mm further.
  const Eigen::Isometry3d T_camera_nail =
      T_camera_guide * pose_from_rotation_vector(Eigen::Vector3d(0.04, -0.05, 0.02), Eigen::Vector3d(2, -3, 60));
  const RobotGoal goal = robot_goal(guide, nail, robot, T_camera_guide, T_camera_nail);
  // At the goal, the guide in the camera frame (the base has not moved):
  const Eigen::Isometry3d T_camera_base = T_camera_guide * (robot.T_base_tip * robot.T_tip_guide).inverse();
  const Eigen::Isometry3d guide_at_goal = T_camera_base * goal.T_base_goal * robot.T_tip_guide;
  for (size_t k = 0; k < 2; ++k) {
    const Eigen::Vector3d p = guide_at_goal * guide.axes[k].point_mm, d = guide_at_goal.linear() * guide.axes[k].direction;
    const Eigen::Vector3d c = T_camera_nail * nail.holes[k].center_mm, z = T_camera_nail.linear().col(2);
    EXPECT_LT(axis_angle_deg(d, z), 1e-6);
    EXPECT_LT(((p - c) - (p - c).dot(z) * z).norm(), 1e-6) << "axis " << k << " off hole " << k;
  }
  // The nearest of the family: a few degrees from now, not a half turn.
  EXPECT_LT(goal.turn_from_now_deg, 10.0);
}

}  // namespace
}  // namespace fluoro
