// The options every command takes (docs/cli.md): --threads N is applied (oneTBB's limit as the
// program reports it) and changes no result; -q prints nothing; -v prints the inputs' digests; and
// fluoro drr's .mha/.nrrd output read back with ITK. Twelve short program runs: 3 s on the 2-core
// machine under a load of 13, about 1 s idle.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "datasets/c_arm.hpp"
#include "engine/image_io.hpp"
#include "engine/json_io.hpp"
#include "engine/sha256.hpp"
#include "kernels/cpu/simd_targets.hpp"
#include "tests/cli_fixture.hpp"
#include "tests/itk_files.hpp"

namespace fluoro {
namespace {

using test::CliResult;

class GlobalOptionsCli : public test::CliTest {
 protected:
  void SetUp() override {
    CliTest::SetUp();
    CArmGeometry g;
    g.pixels = 48;
    g.pixel_mm = 4.0;
    PinholeCamera cam = c_arm_view(g, 0);
    cam.pixel_spacing_mm = Eigen::Vector2d(0.75, 0.5);  // unequal, so rows and columns cannot be swapped unseen
    write_camera(cam, path("cam.json"));
  }
};

TEST_F(GlobalOptionsCli, ThreadsAreAppliedAndChangeNoResult) {
  ASSERT_EQ(run("phantom --kind femur --size 40 --out " + path("ct.nii.gz")).code, 0);
  const std::string drr = "drr --ct " + path("ct.nii.gz") + " --camera " + path("cam.json");
  ASSERT_EQ(run(drr + " --out " + path("all.tif")).code, 0);
  // Before the subcommand or after it: the same option.
  ASSERT_EQ(run("--threads 1 " + drr + " --out " + path("one.tif")).code, 0);
  ASSERT_EQ(run(drr + " --threads 1 --out " + path("one.mha")).code, 0);
  const Image all = read_image(path("all.tif")), one = read_image(path("one.tif"));
  EXPECT_EQ(one.pixels, all.pixels);  // bit for bit: every pixel is one thread's work either way
  float peak = 0;
  for (float v : all.pixels) peak = std::max(peak, v);
  EXPECT_GT(peak, 1.0f);  // a DRR with bone in it, not an empty image

  // The .mha holds the same line integrals with the camera's pixel spacing, row 0 first.
  const auto mha = test::read_itk_image_2d(path("one.mha"));
  EXPECT_DOUBLE_EQ(mha->GetSpacing()[0], 0.75);
  EXPECT_DOUBLE_EQ(mha->GetSpacing()[1], 0.5);
  ASSERT_EQ(mha->GetLargestPossibleRegion().GetSize()[0], 48u);
  for (int v = 0; v < 48; v += 7)
    for (int u = 0; u < 48; u += 5) EXPECT_EQ(mha->GetPixel({{u, v}}), all.at(u, v)) << u << "," << v;

  // The limit as oneTBB applies it, shown by `devices` and recorded in result files.
  EXPECT_NE(run("--threads 1 devices").out.find("threads: at most 1 per parallel loop"), std::string::npos);
  EXPECT_NE(run("devices --threads 3").out.find("threads: at most 3 per parallel loop"), std::string::npos);
  expect_bad_input(run("--threads 0 devices"), "--threads");
}

TEST_F(GlobalOptionsCli, QuietPrintsNothingVerbosePrintsTheDigests) {
  const CliResult phantom = run("-q phantom --kind femur --size 24 --out " + path("ct.nii.gz"));
  EXPECT_EQ(phantom.code, 0);
  EXPECT_EQ(phantom.out + phantom.err, "");
  EXPECT_TRUE(std::filesystem::exists(path("ct.nii.gz")));
  const CliResult drr = run("drr --ct " + path("ct.nii.gz") + " --camera " + path("cam.json") + " --out " +
                            path("d.nrrd") + " --quiet");
  EXPECT_EQ(drr.code, 0) << drr.err;
  EXPECT_EQ(drr.out + drr.err, "");
  EXPECT_DOUBLE_EQ(test::read_itk_image_2d(path("d.nrrd"))->GetSpacing()[0], 0.75);

  write_text("fixed.json", R"({"points": [[0, 0, 0], [50, 0, 0], [0, 40, 0], [0, 0, 30], [20, 20, 20]]})");
  write_text("moving.json", R"({"points": [[5, 0, 0], [55, 0, 0], [5, 40, 0], [5, 0, 30], [25, 20, 20]]})");
  const std::string reg = "register-points --fixed " + path("fixed.json") + " --moving " + path("moving.json");
  const CliResult quiet = run(reg + " --out " + path("q.json") + " -q");
  EXPECT_EQ(quiet.code, 0);
  EXPECT_EQ(quiet.out + quiet.err, "");
  const CliResult loud = run("-v --threads 1 " + reg + " --out " + path("v.json"));
  ASSERT_EQ(loud.code, 0) << loud.err;
  EXPECT_NE(loud.out.find("FRE rms"), std::string::npos) << loud.out;
  EXPECT_NE(loud.err.find("sha256 " + sha256_file(path("fixed.json")) + "  " + path("fixed.json")), std::string::npos)
      << loud.err;
  EXPECT_NE(loud.err.find("at most 1 threads"), std::string::npos) << loud.err;
  const nlohmann::json doc = read_json(path("v.json"));
  expect_provenance(doc, "register-points");
  EXPECT_EQ(doc["provenance"]["threads"], 1);
  EXPECT_EQ(doc["provenance"]["arguments"].front(), "-v");
  EXPECT_EQ(doc["T_fixed_moving"][0][3], -5.0);  // the documented fields are all still there
  EXPECT_EQ(run("-q -v devices").code, 2);
}

// --simd caps the cpu kernels' instruction set: `devices` and the provenance show the set in force,
// the capped DRR agrees with the best set's within the kernels' tolerance (so it is the same op on
// other lanes, not another one), and a name the machine does not offer is refused with the choices.
TEST_F(GlobalOptionsCli, SimdCapIsAppliedAndRecorded) {
  const std::vector<std::string> sets = cpu::simd_targets();
  ASSERT_GE(sets.size(), 2u);  // at least one SIMD set and the portable EMU128 (or SCALAR) code
  const std::string best = sets.front(), last = sets.back();
  EXPECT_NE(run("devices").out.find("cpu SIMD: " + best + " "), std::string::npos);
  EXPECT_NE(run("--simd " + sets[1] + " devices").out.find("cpu SIMD: " + sets[1] + " "), std::string::npos);

  ASSERT_EQ(run("phantom --kind femur --size 40 --out " + path("ct.nii.gz")).code, 0);
  const std::string drr = "drr --ct " + path("ct.nii.gz") + " --camera " + path("cam.json");
  ASSERT_EQ(run(drr + " --out " + path("best.tif")).code, 0);
  const CliResult capped = run("-v " + drr + " --simd " + last + " --out " + path("last.tif"));
  ASSERT_EQ(capped.code, 0) << capped.err;
  EXPECT_NE(capped.err.find("cpu kernels on " + last), std::string::npos) << capped.err;  // what the dispatch runs
  const Image a = read_image(path("best.tif")), b = read_image(path("last.tif"));
  ASSERT_EQ(a.pixels.size(), b.pixels.size());
  float peak = 0;
  for (size_t i = 0; i < a.pixels.size(); ++i) {
    EXPECT_NEAR(b.pixels[i], a.pixels[i], 1e-4f * (1 + std::abs(a.pixels[i]))) << i;
    peak = std::max(peak, a.pixels[i]);
  }
  EXPECT_GT(peak, 1.0f);

  write_text("fixed.json", R"({"points": [[0, 0, 0], [50, 0, 0], [0, 40, 0], [0, 0, 30]]})");
  write_text("moving.json", R"({"points": [[5, 0, 0], [55, 0, 0], [5, 40, 0], [5, 0, 30]]})");
  ASSERT_EQ(run("--simd " + last + " register-points --fixed " + path("fixed.json") + " --moving " +
                path("moving.json") + " --out " + path("r.json")).code, 0);
  EXPECT_EQ(read_json(path("r.json"))["provenance"]["cpu_simd"], last);
  expect_bad_input(run("--simd avx1024 devices"), "--simd");
}

}  // namespace
}  // namespace fluoro
