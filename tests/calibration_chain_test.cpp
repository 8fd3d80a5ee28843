// The calibration chain end to end through the program: `fluoro demo --calibration` (a dewarp grid
// and a phantom X-ray bent by the same image-intensifier distortion), then the real commands on its
// files, `dewarp fit` and `calibrate --dewarp`, against the true camera of the corrected image.
#include <gtest/gtest.h>

#include <filesystem>

#include "datasets/calibration_phantom.hpp"
#include "engine/json_io.hpp"
#include "engine/phantom_model.hpp"
#include "pipelines/calibration/volume_reprojection.hpp"
#include "tests/cli_fixture.hpp"

namespace fluoro {
namespace {

class CalibrationChain : public test::CliTest {
 protected:
  // The demo at 512^2 into the test's directory; its summary.
  nlohmann::json run_demo() const {
    const test::CliResult r = run("demo --calibration --pixels 512 --out-dir " + path("demo"));
    EXPECT_EQ(r.code, 0) << r.err;
    return read_json(path("demo/summary.json"));
  }
  double volume_gap_px(const std::string& estimate) const {
    const PhantomModel phantom = read_phantom_model(path("demo/PHANTOM.json"));
    Eigen::Vector3d lo, hi;
    fiducial_bounds(phantom, &lo, &hi);
    return volume_reprojection_gap(read_camera(estimate), read_camera(path("demo/truth_camera.json")), lo, hi).mean_px;
  }
};

TEST_F(CalibrationChain, DemoMeetsTheGoalsAndTheDewarpIsWhatMakesItAccurate) {
  const nlohmann::json s = run_demo();
  ASSERT_EQ(s["status"], "ok");
  // The noisy goals: dewarp <= 0.05 mm mean and 0.2 mm max between the holes (plate mm);
  // camera <= 0.15 px mean through the phantom's volume.
  EXPECT_LT(s["dewarp"]["error_between_holes_mm"]["mean"].get<double>(), 0.05);
  EXPECT_LT(s["dewarp"]["error_between_holes_mm"]["max"].get<double>(), 0.2);
  const double with = s["calibration"]["volume_reprojection_error_px"]["mean"].get<double>();
  EXPECT_LT(with, 0.15);
  EXPECT_EQ(s["calibration"]["fiducials_matched"], 12);
  // Calibrating the distorted detections directly is measurably worse (0.15 against 0.05 px).
  ASSERT_TRUE(s.contains("calibration_without_dewarp"));
  EXPECT_GT(s["calibration_without_dewarp"]["volume_reprojection_error_px"]["mean"].get<double>(), 2 * with);
}

TEST_F(CalibrationChain, FitAndCalibrateWithTheMapDescribeTheCorrectedImage) {
  run_demo();
  const test::CliResult fit =
      run("dewarp fit --image " + path("demo/grid_xray.png") + " --grid " + path("demo/GRID.json") + " --out " + path("map.json"));
  ASSERT_EQ(fit.code, 0) << fit.err;
  const test::CliResult cal = run("calibrate --image " + path("demo/phantom_xray.png") + " --phantom " +
                                  path("demo/PHANTOM.json") + " --dewarp " + path("map.json") + " --out " +
                                  path("camera.json") + " --overlay " + path("overlay.png"));
  ASSERT_EQ(cal.code, 0) << cal.err;
  const nlohmann::json doc = read_json(path("camera.json"));
  EXPECT_EQ(doc["status"], "ok");
  EXPECT_EQ(doc["inputs"]["dewarp"]["path"], path("map.json"));
  EXPECT_EQ(doc["width"], 512);
  // The map the command fitted is the demo's (same image, deterministic), so the demo's truth in
  // the corrected frame is this camera's truth.
  EXPECT_LT(volume_gap_px(path("camera.json")), 0.15);
  EXPECT_TRUE(std::filesystem::exists(path("overlay.png")));

  // Without the map, the same image gives a camera of the distorted image: further from the truth.
  ASSERT_EQ(run("calibrate --image " + path("demo/phantom_xray.png") + " --phantom " + path("demo/PHANTOM.json") +
                " --out " + path("raw.json")).code,
            0);
  EXPECT_GT(volume_gap_px(path("raw.json")), volume_gap_px(path("camera.json")));
}

TEST_F(CalibrationChain, AMapForAnotherImageSizeIsBadInput) {
  run_demo();
  ASSERT_EQ(run("dewarp fit --image " + path("demo/grid_xray.png") + " --grid " + path("demo/GRID.json") + " --out " +
                path("map.json")).code,
            0);
  PhantomView view;
  view.pixels = 400;
  view.pixel_mm = 0.95;
  write_calibration_scene(render_calibration_scene(tower_phantom(), view, {}), path("small"));
  expect_bad_input(run("calibrate --image " + path("small.png") + " --phantom " + path("small_phantom.json") +
                       " --dewarp " + path("map.json") + " --out " + path("camera.json")),
                   "map.json", "camera.json");
}

}  // namespace
}  // namespace fluoro
