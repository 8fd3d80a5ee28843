// The imaging-physics options of fluoro drr, fluoro demo and SWEEP.json: what they compute
// (a closed form through the whole command) and their bad input.
#include <gtest/gtest.h>

#include <algorithm>
#include <string>

#include "datasets/c_arm.hpp"
#include "engine/image_io.hpp"
#include "engine/json_io.hpp"
#include "tests/cli_fixture.hpp"

namespace fluoro {
namespace {

using test::CliResult;

class PhysicsCli : public test::CliTest {
 protected:
  void SetUp() override {
    CliTest::SetUp();
    CArmGeometry g;
    g.pixels = 48;
    g.pixel_mm = 4.0;
    write_camera(c_arm_view(g, 0), path("cam.json"));
  }
};

TEST_F(PhysicsCli, DrrBeamHardeningFollowsItsCurve) {
  ASSERT_EQ(run("phantom --kind femur --size 40 --out " + path("ct.nii.gz")).code, 0);
  const std::string drr = "drr --ct " + path("ct.nii.gz") + " --camera " + path("cam.json") + " --out ";
  ASSERT_EQ(run(drr + path("plain.tif")).code, 0);
  const CliResult r = run(drr + path("hard.tif") + " --beam-hardening 0.06");
  ASSERT_EQ(r.code, 0) << r.err;
  const Image plain = read_image(path("plain.tif")), hard = read_image(path("hard.tif"));
  ASSERT_EQ(plain.pixels.size(), hard.pixels.size());
  const float top = *std::max_element(plain.pixels.begin(), plain.pixels.end());
  const double s = std::min(1.0, 6.0 / top);  // scaled so the thickest ray is at most 6
  ASSERT_GT(top, 1.0f);
  for (size_t i = 0; i < plain.pixels.size(); ++i) {
    const double l = s * plain.pixels[i];
    ASSERT_NEAR(hard.pixels[i], (l - 0.06 * l * l) / s, 1e-4) << i;
  }
}

TEST_F(PhysicsCli, OutOfRangeValuesAndUnknownKeysAreBadInput) {
  const std::string drr = "drr --ct " + path("ct.nii.gz") + " --camera " + path("cam.json") + " --out " + path("d.tif");
  ASSERT_EQ(run("phantom --kind femur --size 40 --out " + path("ct.nii.gz")).code, 0);
  expect_bad_input(run(drr + " --beam-hardening 0.2"), "--beam-hardening", "d.tif");
  expect_bad_input(run(drr + " --photons 0.5"), "--photons", "d.tif");
  expect_bad_input(run(drr + " --scatter -1"), "--scatter", "d.tif");
  expect_bad_input(run("demo --calibration --scatter 0.25 --out-dir " + path("demo")), "apply to the registration demo");

  const std::string sweep = R"({"phantom": {"kind": "femur", "size": 64}, "distances_mm": {"from": 4, "to": 4}, "runs_per_distance": 1, )";
  write_text("typo.json", sweep + R"("physics": {"scater": 0.25}})");
  expect_bad_input(run("sweep --config " + path("typo.json") + " --out " + path("runs.csv")), "unknown key \"scater\"", "runs.csv");
  write_text("range.json", sweep + R"("physics": {"beam_hardening": 0.5}})");
  expect_bad_input(run("sweep --config " + path("range.json") + " --out " + path("runs.csv")), "\"beam_hardening\"", "runs.csv");
  write_text("type.json", sweep + R"("physics": {"photons": "many"}})");
  expect_bad_input(run("sweep --config " + path("type.json") + " --out " + path("runs.csv")), "\"photons\" must be a number", "runs.csv");
  write_text("array.json", sweep + R"("physics": [0.06]})");
  expect_bad_input(run("sweep --config " + path("array.json") + " --out " + path("runs.csv")), "\"physics\" must be an object", "runs.csv");
}

}  // namespace
}  // namespace fluoro
