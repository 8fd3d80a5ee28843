// Camera calibration on generated phantom X-rays with known truth: the DLT, the detector, the
// pairing (clutter rejected), the goals of issue 10 (reprojection through the phantom's volume
// against the true camera) and the command line (exit 3 with a failed result, exit 2 on bad input).
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "datasets/calibration_phantom.hpp"
#include "engine/image_io.hpp"
#include "engine/json_io.hpp"
#include "pipelines/calibration/camera_calibration.hpp"
#include "pipelines/calibration/dark_circle_detector.hpp"
#include "pipelines/calibration/projection_dlt.hpp"
#include "pipelines/calibration/volume_reprojection.hpp"
#include "tests/cli_fixture.hpp"

namespace fluoro {
namespace {

namespace fs = std::filesystem;

// The tests' C-arm: 512^2 pixels of 0.76 mm (the 1024^2, 0.38 mm detector binned 2 x 2), so the
// tower's 5 mm balls are 7 to 9 pixels across, as in the seed.
PhantomView test_view() {
  PhantomView v;
  v.pixels = 512;
  v.pixel_mm = 0.76;
  v.axis_turn_deg = 17;
  v.tilt_deg = 4;
  v.tilt_azimuth_deg = 30;
  v.shift_mm = Eigen::Vector2d(6, -4);
  v.principal_offset_px = Eigen::Vector2d(3.5, -2.25);
  return v;
}

XrayRendering noisy() {
  XrayRendering r;
  r.blur_sigma_px = 0.7;
  r.photons_per_pixel = 150;
  return r;
}

struct Outcome {
  CameraCalibration cal;
  ReprojectionGap gap;
  std::vector<DarkCircle> circles;
  CalibrationScene scene;
};

Outcome calibrate_scene(const PhantomModel& phantom, const PhantomView& view, const XrayRendering& r) {
  Outcome o;
  o.scene = render_calibration_scene(phantom, view, r);
  const Image img = log_domain_xray(o.scene.line_integral);
  o.circles = detect_dark_circles(img);
  std::vector<DetectedCentre> centres;
  for (const auto& c : o.circles) centres.push_back({c.centre_px, c.crowded});
  o.cal = calibrate_camera(phantom, centres, img.width, img.height);
  if (o.cal.ok) {
    Eigen::Vector3d lo, hi;
    fiducial_bounds(phantom, &lo, &hi);
    o.gap = volume_reprojection_gap(o.cal.camera, o.scene.camera, lo, hi);
  }
  return o;
}

TEST(CameraCalibration, DltRecoversAnExactProjection) {
  const PinholeCamera truth = phantom_view_camera(test_view());
  std::vector<Eigen::Vector3d> X;
  std::vector<Eigen::Vector2d> x;
  for (const auto& f : tower_phantom().fiducials) X.push_back(f.position_mm), x.push_back(truth.project(f.position_mm));
  const auto P = projection_dlt(X, x);
  ASSERT_TRUE(P);
  const PinholeCamera c = camera_from_projection(*P, 512, 512, "test");
  EXPECT_NEAR(c.K(0, 0), truth.K(0, 0), 1e-6 * truth.K(0, 0));
  EXPECT_NEAR(c.K(0, 2), truth.K(0, 2), 1e-6);
  EXPECT_LT((c.source() - truth.source()).norm(), 1e-6);
  // Coplanar points leave P undetermined.
  std::vector<Eigen::Vector3d> flat = X;
  for (auto& p : flat) p.z() = 0;
  std::vector<Eigen::Vector2d> fx;
  for (const auto& p : flat) fx.push_back(truth.project(p));
  EXPECT_FALSE(projection_dlt(flat, fx));
}

TEST(CameraCalibration, TowerCleanIsRecoveredExactly) {
  const Outcome o = calibrate_scene(tower_phantom(), test_view(), {});
  ASSERT_TRUE(o.cal.ok) << o.cal.failure_reason;
  EXPECT_EQ(o.cal.fiducials.size(), 12u);
  std::printf("tower clean: mean %.4f max %.4f px, source %.3f mm, rms %.4f\n", o.gap.mean_px, o.gap.max_px,
              (o.cal.camera.source() - o.scene.camera.source()).norm(), o.cal.rms_px);
  EXPECT_LT(o.gap.mean_px, 0.02);
  EXPECT_LT((o.cal.camera.source() - o.scene.camera.source()).norm(), 0.5);
}

TEST(CameraCalibration, TowerNoisyMeetsTheGoal) {
  const Outcome o = calibrate_scene(tower_phantom(), test_view(), noisy());
  ASSERT_TRUE(o.cal.ok) << o.cal.failure_reason;
  std::printf("tower noisy: mean %.4f max %.4f px, source %.3f mm, rms %.4f\n", o.gap.mean_px, o.gap.max_px,
              (o.cal.camera.source() - o.scene.camera.source()).norm(), o.cal.rms_px);
  EXPECT_LT(o.gap.mean_px, 0.15);
}

TEST(CameraCalibration, RingCleanAndNoisy) {
  const Outcome a = calibrate_scene(ring_phantom(), test_view(), {});
  ASSERT_TRUE(a.cal.ok) << a.cal.failure_reason;
  std::printf("ring clean: mean %.4f max %.4f px, source %.3f mm, rms %.4f\n", a.gap.mean_px, a.gap.max_px,
              (a.cal.camera.source() - a.scene.camera.source()).norm(), a.cal.rms_px);
  EXPECT_LT(a.gap.mean_px, 0.02);
  const Outcome b = calibrate_scene(ring_phantom(), test_view(), noisy());
  ASSERT_TRUE(b.cal.ok) << b.cal.failure_reason;
  std::printf("ring noisy: mean %.4f max %.4f px, source %.3f mm, rms %.4f\n", b.gap.mean_px, b.gap.max_px,
              (b.cal.camera.source() - b.scene.camera.source()).norm(), b.cal.rms_px);
  EXPECT_LT(b.gap.mean_px, 0.15);
}


// The pairing ignores blobs that belong to no fiducial: clutter balls and wires are found by the
// detector or not, but never paired, and every pairing is the right one.
TEST(CameraCalibration, ClutterIsRejected) {
  XrayRendering r = noisy();
  r.clutter_balls = 4;
  r.clutter_wires = 2;
  r.seed = 3;
  const PhantomModel tower = tower_phantom();
  const Outcome o = calibrate_scene(tower, test_view(), r);
  ASSERT_TRUE(o.cal.ok) << o.cal.failure_reason;
  EXPECT_GT(o.circles.size(), 12u);  // clutter balls were detected...
  EXPECT_GE(o.cal.fiducials.size(), 10u);
  for (const auto& f : o.cal.fiducials) {  // ...and none was paired: each pair is its own ball
    const Eigen::Vector2d truth = o.scene.camera.project(tower.fiducials[size_t(f.fiducial)].position_mm);
    EXPECT_LT((f.pixel - truth).norm(), 0.5) << tower.fiducials[size_t(f.fiducial)].id;
    for (const auto& c : o.scene.clutter_balls_mm) EXPECT_GT((f.pixel - o.scene.camera.project(c)).norm(), 3.0);
  }
  std::printf("tower noisy with clutter: %zu blobs, %zu paired, mean %.4f max %.4f px\n", o.circles.size(),
              o.cal.fiducials.size(), o.gap.mean_px, o.gap.max_px);
  EXPECT_LT(o.gap.mean_px, 0.15);
}

TEST(CameraCalibration, TooFewBallsFailsWithAReason) {
  PhantomModel five = tower_phantom();
  five.fiducials.resize(5);
  const CalibrationScene scene = render_calibration_scene(five, test_view(), {});
  std::vector<DetectedCentre> centres;
  for (const auto& c : detect_dark_circles(log_domain_xray(scene.line_integral))) centres.push_back({c.centre_px, c.crowded});
  EXPECT_EQ(centres.size(), 5u);
  const CameraCalibration cal = calibrate_camera(tower_phantom(), centres, 512, 512);
  EXPECT_FALSE(cal.ok);
  EXPECT_NE(cal.failure_reason.find("6"), std::string::npos) << cal.failure_reason;
}

// Only one level of the ring phantom in the image: its balls are coplanar, one image of them
// cannot fix the camera, and the calibration says so instead of guessing.
TEST(CameraCalibration, CoplanarFiducialsFail) {
  PhantomModel ring = ring_phantom();
  PhantomModel lower = ring;
  lower.fiducials.resize(8);  // 8 balls of the z = 10 mm ring (fewer hypotheses to exhaust)
  const CalibrationScene scene = render_calibration_scene(lower, test_view(), {});
  std::vector<DetectedCentre> centres;
  for (const auto& c : detect_dark_circles(log_domain_xray(scene.line_integral))) centres.push_back({c.centre_px, c.crowded});
  EXPECT_EQ(centres.size(), 8u);
  const CameraCalibration cal = calibrate_camera(ring, centres, 512, 512);
  EXPECT_FALSE(cal.ok);
  EXPECT_NE(cal.failure_reason.find("coplanar"), std::string::npos) << cal.failure_reason;
}

// A C-arm orientation where the tower is seen 15 degrees off its axis, with noise and clutter.
TEST(CameraCalibration, ObliqueViewMeetsTheGoal) {
  PhantomView v = test_view();
  v.tilt_deg = 15;
  v.tilt_azimuth_deg = 110;
  XrayRendering r = noisy();
  r.clutter_balls = 2;
  r.seed = 5;
  const Outcome o = calibrate_scene(tower_phantom(), v, r);
  ASSERT_TRUE(o.cal.ok) << o.cal.failure_reason;
  std::printf("tower oblique noisy: mean %.4f max %.4f px\n", o.gap.mean_px, o.gap.max_px);
  EXPECT_LT(o.gap.mean_px, 0.15);
}

// The tower turned about its axis in steps of 30 degrees (and tilted 0, 6, 12 degrees): the
// pairing follows from the pattern in every turn, and two balls that overlap in one of these
// views (turn 60, tilt 12) are found as one elongated blob, which is left out of the fit instead
// of pulling it (before: a mean of 0.34 px).
TEST(CameraCalibration, EveryTurnOfTheTowerIsPaired) {
  const PhantomModel tower = tower_phantom();
  Eigen::Vector3d lo, hi;
  fiducial_bounds(tower, &lo, &hi);
  for (int turn = 0; turn < 360; turn += 30) {
    PhantomView v = test_view();
    v.axis_turn_deg = turn;
    v.tilt_deg = (turn / 30) % 3 * 6;
    v.tilt_azimuth_deg = turn * 1.7;
    const CalibrationScene scene = render_calibration_scene(tower, v, {});
    std::vector<DetectedCentre> centres;
    for (const auto& c : detect_dark_circles(log_domain_xray(scene.line_integral))) centres.push_back({c.centre_px, c.crowded});
    const CameraCalibration cal = calibrate_camera(tower, centres, 512, 512);
    ASSERT_TRUE(cal.ok) << "turn " << turn << ": " << cal.failure_reason;
    EXPECT_GE(cal.fiducials.size(), 10u) << "turn " << turn;
    EXPECT_LT(volume_reprojection_gap(cal.camera, scene.camera, lo, hi).mean_px, 0.02) << "turn " << turn;
  }
}

// Four noisy images of the tower at one C-arm orientation, the phantom turned and shifted between
// them: with one K shared by all, the cameras reproject the phantom's volume better than the
// single images' cameras on average (measured: a third better).
TEST(CameraCalibration, SeveralImagesRefineOneK) {
  const PhantomModel tower = tower_phantom();
  std::vector<std::vector<DetectedCentre>> images;
  std::vector<CalibrationScene> scenes;
  for (int k = 0; k < 4; ++k) {
    PhantomView v = test_view();
    v.axis_turn_deg = 17 + 40 * k;
    v.shift_mm = Eigen::Vector2d(6 - 8 * k, -4 + 5 * k);
    XrayRendering r = noisy();
    r.seed = uint64_t(11 + k);
    scenes.push_back(render_calibration_scene(tower, v, r));
    std::vector<DetectedCentre> centres;
    for (const auto& c : detect_dark_circles(log_domain_xray(scenes.back().line_integral))) centres.push_back({c.centre_px, c.crowded});
    images.push_back(centres);
  }
  const double f_true = scenes[0].camera.K(0, 0);
  double single_error = 0, single_gap = 0;
  Eigen::Vector3d lo, hi;
  fiducial_bounds(tower, &lo, &hi);
  for (size_t k = 0; k < 4; ++k) {
    const CameraCalibration one = calibrate_camera(tower, images[k], 512, 512);
    ASSERT_TRUE(one.ok) << one.failure_reason;
    single_error += std::abs(one.camera.K(0, 0) - f_true) / 4;
    single_gap += volume_reprojection_gap(one.camera, scenes[k].camera, lo, hi).mean_px / 4;
  }
  const std::vector<CameraCalibration> joint = calibrate_camera_views(tower, images, 512, 512);
  ASSERT_EQ(joint.size(), 4u);
  double joint_gap = 0;
  for (size_t k = 0; k < 4; ++k) {
    ASSERT_TRUE(joint[k].ok);
    EXPECT_TRUE(joint[k].camera.K.isApprox(joint[0].camera.K));
    const double g = volume_reprojection_gap(joint[k].camera, scenes[k].camera, lo, hi).mean_px;
    EXPECT_LT(g, 0.15);
    joint_gap += g / 4;
  }
  const double joint_error = std::abs(joint[0].camera.K(0, 0) - f_true);
  std::printf("volume gap: single images %.4f px, shared K %.4f px; focal length error %.2f and %.2f px\n",
              single_gap, joint_gap, single_error, joint_error);
  EXPECT_LT(joint_gap, 0.85 * single_gap);
}

// The perspective image of a sphere is not centred on the projection of its centre. The detector
// takes the centroid of the line integrals; under a central projection that centroid is the
// sphere's volume integral of u(X) weighted by l / z^3 (l the distance from the source, z the
// depth: the Jacobian from solid angle to image area). Measured here at the issue's 1024^2
// geometry for every tower ball: it stays under 0.005 px, a quarter of the 0.02 px goal, so the
// calibration does not correct for it (docs/calibration.md).
TEST(CameraCalibration, SphereImageCentroidOffsetIsNegligible) {
  PhantomView v;  // 1024^2, 0.38 mm
  v.shift_mm = Eigen::Vector2d(40, 30);  // the phantom pushed off-axis: larger angles
  const PinholeCamera cam = phantom_view_camera(v);
  const PhantomModel tower = tower_phantom();
  const double r = 0.5 * tower.fiducial_diameter_mm;
  const int n = 48;
  double worst = 0;
  for (const auto& f : tower.fiducials) {
    const Eigen::Vector3d c = cam.R * f.position_mm + cam.t;
    Eigen::Vector2d sum = Eigen::Vector2d::Zero();
    double wsum = 0;
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j)
        for (int k = 0; k < n; ++k) {
          const Eigen::Vector3d q = (Eigen::Vector3d(i, j, k) + Eigen::Vector3d::Constant(0.5)) * (2.0 / n) -
                                    Eigen::Vector3d::Ones();
          if (q.squaredNorm() > 1) continue;
          const Eigen::Vector3d x = c + r * q;
          const double w = x.norm() / (x.z() * x.z() * x.z());
          sum += w * (cam.K * (x / x.z())).head<2>();
          wsum += w;
        }
    const Eigen::Vector3d pc = cam.K * (c / c.z());
    worst = std::max(worst, (sum / wsum - pc.head<2>()).norm());
  }
  std::printf("largest centroid offset of a tower ball's image: %.5f px\n", worst);
  EXPECT_GT(worst, 1e-4);  // the effect is there (the quadrature sees it)...
  EXPECT_LT(worst, 0.005);  // ...and negligible at the goal
}

// Balls 3 to 4 px across (the tower's 5 mm balls on 1.8 mm pixels): found and calibrated all the same.
TEST(CameraCalibration, SmallBallsAreFoundAndCalibrated) {
  PhantomView v = test_view();
  v.pixels = 256;
  v.pixel_mm = 1.8;
  v.principal_offset_px = Eigen::Vector2d(1.5, -1);
  const Outcome o = calibrate_scene(tower_phantom(), v, {});
  EXPECT_EQ(o.circles.size(), 12u);
  ASSERT_TRUE(o.cal.ok) << o.cal.failure_reason;
  EXPECT_EQ(o.cal.fiducials.size(), 12u);
  EXPECT_LT(o.gap.mean_px, 0.05);
}

// The command line: CAMERA.json is a camera file, a failure writes status "failed" and exits 3,
// bad input exits 2 with one line and writes nothing.
class CalibrateCli : public test::CliTest {
 protected:
  void SetUp() override {
    CliTest::SetUp();
    write_json(phantom_model_to_json(tower_phantom()), path("phantom.json"));
  }
  CalibrationScene write_scene(const PhantomModel& phantom, const std::string& name) const {
    CalibrationScene scene = render_calibration_scene(phantom, test_view(), {});
    write_calibration_scene(scene, path(name));
    return scene;
  }
};

TEST_F(CalibrateCli, WritesACameraFileOfThePhantomFrame) {
  write_scene(tower_phantom(), "tower");
  const test::CliResult r = run("calibrate --image " + path("tower.png") + " --phantom " + path("tower_phantom.json") +
                                " --out " + path("camera.json") + " --overlay " + path("overlay.png"));
  ASSERT_EQ(r.code, 0) << r.err;
  const PinholeCamera cam = read_camera(path("camera.json"));
  Eigen::Vector3d lo, hi;
  fiducial_bounds(tower_phantom(), &lo, &hi);
  EXPECT_LT(volume_reprojection_gap(cam, read_camera(path("tower_true_camera.json")), lo, hi).mean_px, 0.02);
  const nlohmann::json doc = read_json(path("camera.json"));
  EXPECT_EQ(doc["status"], "ok");
  expect_provenance(doc, "calibrate");
  EXPECT_EQ(doc["fiducials_found"], 12);
  EXPECT_EQ(doc["fiducials_matched"].size(), 12u);
  EXPECT_EQ(doc["backprojection_mm"].size(), 12u);
  EXPECT_LT(doc["reprojection_px"]["rms"].get<double>(), 0.05);
  for (const auto& b : doc["backprojection_mm"]) EXPECT_LT(b["distance_mm"].get<double>(), 0.05);
  EXPECT_TRUE(doc["inputs"].contains("image"));
  EXPECT_TRUE(doc["timings_s"].contains("detect"));
  EXPECT_TRUE(fs::exists(path("overlay.png")));
}

TEST_F(CalibrateCli, FiveBallsExitThreeWithAFailedResult) {
  PhantomModel five = tower_phantom();
  five.fiducials.resize(5);
  write_scene(five, "five");
  const test::CliResult r =
      run("calibrate --image " + path("five.png") + " --phantom " + path("phantom.json") + " --out " + path("camera.json"));
  const nlohmann::json doc = expect_failed(r, "camera.json", {"K", "R", "t"});  // never a guessed camera
  EXPECT_FALSE(doc["reason"].get<std::string>().empty());
}

TEST_F(CalibrateCli, BadInputExitsTwoAndWritesNothing) {
  write_scene(tower_phantom(), "tower");
  write_text("nan.json", R"({"kind": "fiducial_phantom", "fiducial_diameter_mm": 5, "fiducials": [)"
                         R"({"id": "a", "position_mm": [1, NaN, 3]}]})");
  const std::string out = " --out " + path("camera.json");
  expect_bad_input(run("calibrate --image " + path("tower.png") + " --phantom " + path("nan.json") + out), "nan.json",
                   "camera.json");
  write_text("short.json", R"({"kind": "fiducial_phantom", "fiducial_diameter_mm": 5, "fiducials": [)"
                           R"({"id": "a", "position_mm": [1, 2]}]})");
  expect_bad_input(run("calibrate --image " + path("tower.png") + " --phantom " + path("short.json") + out),
                   "short.json", "camera.json");
  expect_bad_input(run("calibrate --image " + path("missing.png") + " --phantom " + path("phantom.json") + out),
                   "missing.png", "camera.json");
  expect_bad_input(run("calibrate --image " + path("tower.png") + " --phantom " + path("phantom.json") + out +
                       " --bogus 1"),
                   "--bogus", "camera.json");
  // A bad second output: the first (the overlay) is not written either.
  expect_bad_input(run("calibrate --image " + path("tower.png") + " --phantom " + path("phantom.json") + " --overlay " +
                       path("overlay.png") + " --out " + path("no/camera.json")),
                   "no/camera.json", "overlay.png");
}

}  // namespace
}  // namespace fluoro
