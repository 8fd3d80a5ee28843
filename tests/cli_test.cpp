// The fluoro program end to end: successful runs write their outputs; bad input gives a one-line
// message naming the file, exit code 2, and no output (an older output stays intact).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "datasets/c_arm.hpp"
#include "engine/image_io.hpp"
#include "engine/json_io.hpp"
#include "engine/pose.hpp"
#include "engine/version.hpp"
#include "tests/cli_fixture.hpp"
#include "tests/itk_files.hpp"

namespace fluoro {
namespace {

namespace fs = std::filesystem;

using test::CliResult;

class Cli : public test::CliTest {
 protected:
  void SetUp() override {
    CliTest::SetUp();
    CArmGeometry g;
    g.pixels = 48;
    g.pixel_mm = 4.0;
    write_camera(c_arm_view(g, 0), path("cam.json"));
  }
  // A MetaImage with a hand-written header: 4^3 floats.
  void write_mha(const std::string& name, const std::string& spacing, float value) const {
    std::ofstream f(path(name), std::ios::binary);
    f << "ObjectType = Image\nNDims = 3\nDimSize = 4 4 4\nElementType = MET_FLOAT\nElementSpacing = " << spacing
      << "\nElementDataFile = LOCAL\n";
    for (int i = 0; i < 64; ++i) f.write(reinterpret_cast<const char*>(&value), sizeof value);
  }
};

TEST_F(Cli, PhantomThenDrrWritesBothFormats) {
  ASSERT_EQ(run("phantom --kind femur --size 40 --out " + path("ct.nii.gz")).code, 0);
  const CliResult a = run("drr --ct " + path("ct.nii.gz") + " --camera " + path("cam.json") + " --out " + path("d.tif"));
  ASSERT_EQ(a.code, 0) << a.err;
  const CliResult b = run("drr --ct " + path("ct.nii.gz") + " --camera " + path("cam.json") + " --out " + path("d.png") +
                    " --backend reference --step 2");
  ASSERT_EQ(b.code, 0) << b.err;
  EXPECT_TRUE(fs::exists(path("d.tif")));
  EXPECT_TRUE(fs::exists(path("d.png")));
  const CliResult info = run("info " + path("d.tif"));
  EXPECT_EQ(info.code, 0);
  EXPECT_NE(info.out.find("48 x 48"), std::string::npos) << info.out;
}

// A DRR written in a volume's format (.nii, .mha, .nrrd) is a 2D image: `info` shows it as one,
// with the same pixels as the float TIFF of the same render, and not as a 3D volume it is not.
TEST_F(Cli, DrrsInVolumeFormatsAreImagesToInfo) {
  ASSERT_EQ(run("phantom --kind femur --size 24 --out " + path("ct.nii.gz")).code, 0);
  const auto values_line = [](const std::string& out) {
    const size_t at = out.find("values");
    return at == std::string::npos ? std::string() : out.substr(at, out.find('\n', at) - at);
  };
  std::string tif_values;
  for (const char* name : {"d.tif", "d.nii", "d.mha", "d.nrrd"}) {
    SCOPED_TRACE(name);
    const CliResult drr = run("drr --ct " + path("ct.nii.gz") + " --camera " + path("cam.json") + " --out " + path(name));
    ASSERT_EQ(drr.code, 0) << drr.err;
    const CliResult info = run("info " + path(name));
    ASSERT_EQ(info.code, 0) << info.err;
    EXPECT_NE(info.out.find(": image"), std::string::npos) << info.out;
    EXPECT_NE(info.out.find("48 x 48 pixels"), std::string::npos) << info.out;
    if (tif_values.empty()) tif_values = values_line(info.out);
    EXPECT_EQ(values_line(info.out), tif_values);
  }
  EXPECT_NE(tif_values.find("values"), std::string::npos);
  // The CT itself is still a volume.
  const CliResult ct = run("info " + path("ct.nii.gz"));
  ASSERT_EQ(ct.code, 0) << ct.err;
  EXPECT_NE(ct.out.find(": volume"), std::string::npos) << ct.out;
}

TEST_F(Cli, VersionIsTheProjectVersion) {
  const CliResult r = run("--version");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.out, std::string("fluoro ") + FLUORO_VERSION + "\n");
  EXPECT_EQ(std::string(FLUORO_VERSION), std::to_string(FLUORO_VERSION_MAJOR) + "." +
                                             std::to_string(FLUORO_VERSION_MINOR) + "." +
                                             std::to_string(FLUORO_VERSION_PATCH));
}

TEST_F(Cli, DevicesListsTheBackends) {
  const CliResult r = run("devices");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("backends: cpu, reference"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("vulkan devices"), std::string::npos) << r.out;
}

#if FLUORO_HAVE_VULKAN
TEST_F(Cli, VulkanDrrMatchesCpuAndBadDevicesAreBadInput) {
  if (run("devices").out.find("vulkan devices: none") != std::string::npos) GTEST_SKIP() << "no Vulkan device";
  ASSERT_EQ(run("phantom --kind femur --size 40 --out " + path("ct.nii.gz")).code, 0);
  const std::string drr = "drr --ct " + path("ct.nii.gz") + " --camera " + path("cam.json");
  const CliResult v = run(drr + " --out " + path("v.tif") + " --backend vulkan:0");
  ASSERT_EQ(v.code, 0) << v.err;
  EXPECT_NE(v.out.find("backend vulkan"), std::string::npos) << v.out;
  const CliResult c = run(drr + " --out " + path("c.tif"));
  ASSERT_EQ(c.code, 0) << c.err;
  // The same DRR as the cpu backend's, pixel for pixel (within the backends' equivalence tolerance).
  const Image vi = read_image(path("v.tif")), ci = read_image(path("c.tif"));
  ASSERT_EQ(vi.width, 48);
  ASSERT_EQ(vi.height, 48);
  ASSERT_EQ(vi.pixels.size(), ci.pixels.size());
  float peak = 0, largest_difference = 0;
  for (size_t i = 0; i < ci.pixels.size(); ++i) {
    peak = std::max(peak, ci.pixels[i]);
    largest_difference = std::max(largest_difference, std::abs(vi.pixels[i] - ci.pixels[i]));
  }
  EXPECT_GT(peak, 0.5f);  // the phantom is in the image
  EXPECT_LT(largest_difference, 1e-4f * peak);
  expect_bad_input(run(drr + " --out " + path("o.tif") + " --backend vulkan:99"), "no Vulkan device 99");
  expect_bad_input(run(drr + " --out " + path("o.tif") + " --backend vulkan:abc"), "vulkan:abc");
  // No driver at all (the loader pointed at no ICD): a clear one-line error naming what was looked for.
  expect_bad_input(run(drr + " --out " + path("o.tif") + " --backend vulkan", "VK_ICD_FILENAMES=/nonexistent.json"),
                   "no Vulkan device found");
  EXPECT_FALSE(fs::exists(path("o.tif")));
}
#endif

TEST_F(Cli, InfoOnTheRealPelvisShowsItsLpsGeometry) {
  const std::string ct = std::string(FLUORO_SHARED_DATASETS) + "/pelvis-ct/ct.nii.gz";
  if (!fs::exists(ct)) GTEST_SKIP() << "no " << ct;
  const CliResult r = run("info " + ct);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("122 x 101 x 112"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("spacing    3 3 3"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("direction  [-1 0 0; 0 -1 0; 0 0 1]"), std::string::npos) << r.out;
}

TEST_F(Cli, MissingCtIsBadInput) {
  const CliResult r = run("drr --ct " + path("nope.nii.gz") + " --camera " + path("cam.json") + " --out " + path("o.tif"));
  expect_bad_input(r, "nope.nii.gz");
  EXPECT_FALSE(fs::exists(path("o.tif")));
}

TEST_F(Cli, TruncatedNiftiIsBadInputAndKeepsTheOldOutput) {
  ASSERT_EQ(run("phantom --size 32 --out " + path("ct.nii.gz")).code, 0);
  const auto size = fs::file_size(path("ct.nii.gz"));
  fs::resize_file(path("ct.nii.gz"), size / 2);
  write_text("o.tif", "old output");
  const CliResult r = run("drr --ct " + path("ct.nii.gz") + " --camera " + path("cam.json") + " --out " + path("o.tif"));
  expect_bad_input(r, "ct.nii.gz");
  EXPECT_EQ(slurp(path("o.tif")), "old output");
}

TEST_F(Cli, NanVoxelsAreBadInput) {
  write_mha("nan.mha", "1 1 1", std::nanf(""));
  expect_bad_input(run("info " + path("nan.mha")), "nan.mha");
}

TEST_F(Cli, ZeroSpacingIsBadInput) {
  write_mha("flat.mha", "0 1 1", 1.0f);
  expect_bad_input(run("info " + path("flat.mha")), "flat.mha");
}

TEST_F(Cli, SingularKIsBadInput) {
  write_text("k.json", R"({"width": 8, "height": 8, "K": [[0,0,4],[0,0,4],[0,0,1]],
                           "R": [[1,0,0],[0,1,0],[0,0,1]], "t": [0,0,500]})");
  ASSERT_EQ(run("phantom --size 32 --out " + path("ct.nii.gz")).code, 0);
  const CliResult r = run("drr --ct " + path("ct.nii.gz") + " --camera " + path("k.json") + " --out " + path("o.tif"));
  expect_bad_input(r, "k.json");
  EXPECT_NE(r.err.find("singular"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(path("o.tif")));
}

TEST_F(Cli, ImproperRIsBadInput) {
  write_text("r.json", R"({"width": 8, "height": 8, "K": [[100,0,4],[0,100,4],[0,0,1]],
                           "R": [[-1,0,0],[0,1,0],[0,0,1]], "t": [0,0,500]})");
  const CliResult r = run("info " + path("r.json"));
  expect_bad_input(r, "r.json");
  EXPECT_NE(r.err.find("improper"), std::string::npos) << r.err;
}

TEST_F(Cli, UnknownBackendAndBadOptionsAreBadInput) {
  ASSERT_EQ(run("phantom --size 32 --out " + path("ct.nii.gz")).code, 0);
  expect_bad_input(run("drr --ct " + path("ct.nii.gz") + " --camera " + path("cam.json") + " --out " +
                       path("o.tif") + " --backend quantum"),
                   "quantum");
  EXPECT_EQ(run("drr --ct").code, 2);
  EXPECT_EQ(run("phantom --kind skull --out " + path("x.nii.gz")).code, 2);
  EXPECT_FALSE(fs::exists(path("x.nii.gz")));
}

TEST_F(Cli, EverySubcommandHasHelp) {
  for (const char* sub : {"info", "drr", "phantom", "demo", "register", "sweep", "devices", "dewarp", "dewarp fit",
                          "dewarp apply", "calibrate", "pivot", "register-points", "icp"}) {
    const CliResult r = run(std::string(sub) + " --help");
    EXPECT_EQ(r.code, 0) << sub;
    EXPECT_NE(r.out.find("Usage"), std::string::npos) << sub;
  }
}

TEST_F(Cli, DemoRegistersThePhantomAndWritesItsOutputs) {
  const CliResult r = run("demo --size 64 --pixels 256 --out-dir " + path("demo"));
  ASSERT_EQ(r.code, 0) << r.err;
  for (const char* f : {"ap_xray.png", "ap_camera.json", "lateral_tilted_overlay.png", "summary.json", "result.json",
                        "truth_pose.json", "start_pose.json"})
    EXPECT_TRUE(fs::exists(path("demo/" + std::string(f)))) << f;
  const auto summary = read_json(path("demo/summary.json"));
  EXPECT_EQ(summary["status"], "ok");
  EXPECT_NEAR(summary["errors"]["start"]["surface_tre_mean_mm"].get<double>(), 9.5, 0.01);
  // 4 mm voxels and 256^2 X-rays: a coarse scene, still well under 2 mm.
  EXPECT_LT(summary["errors"]["registered"]["surface_tre_mean_mm"].get<double>(), 1.0);
  EXPECT_TRUE(summary["registration"]["confident"].get<bool>());
  // Its result files say what made them: the demo, its settings, and no input files.
  const auto result = read_json(path("demo/result.json"));
  EXPECT_EQ(result["provenance"]["command"], "demo");
  EXPECT_EQ(result["provenance"]["settings"]["size"], 64);
  EXPECT_EQ(result["provenance"]["inputs"], nlohmann::json::array());
  EXPECT_EQ(summary["provenance"], result["provenance"]);
}

// The demo's X-rays, cameras and start pose, registered again through `fluoro register`.
class CliRegister : public Cli {
 protected:
  void SetUp() override {
    Cli::SetUp();
    ASSERT_EQ(run("demo --size 64 --pixels 256 --out-dir " + path("demo")).code, 0);
    ASSERT_EQ(run("phantom --kind femur --size 64 --fiducials --out " + path("ct.nii.gz")).code, 0);
    views_ = " --ct " + path("ct.nii.gz");
    for (const char* v : {"ap", "oblique60", "lateral_tilted"})
      views_ += " --view " + path("demo/" + std::string(v) + "_xray.png") + ":" + path("demo/" + std::string(v) + "_camera.json");
  }
  std::string views_;
};

TEST_F(CliRegister, FromAPoseFileAloneWritesTheResultAndOverlays) {
  const CliResult r = run("register" + views_ + " --init " + path("demo/start_pose.json") + " --out " +
                          path("result.json") + " --overlay-dir " + path("overlays") + " --tfm " + path("r.tfm"));
  ASSERT_EQ(r.code, 0) << r.err;
  const auto result = read_json(path("result.json"));
  EXPECT_EQ(result["status"], "ok");
  EXPECT_TRUE(result["confident"].get<bool>());
  const Pose truth = read_pose(path("demo/truth_pose.json")), found = read_pose(path("result.json"));
  EXPECT_LT((found.translation() - truth.translation()).norm(), 1.5);
  EXPECT_LT(rotation_angle_deg(found * truth.inverse()), 2.0);
  // Coarse and three GPR stages: the polish's default ("auto") leaves DRR-like X-rays alone.
  EXPECT_EQ(result["stages"].size(), 4u);
  EXPECT_EQ(result["provenance"]["settings"]["correlation_polish"], "auto");
  EXPECT_EQ(result["inputs"]["views"].size(), 3u);
  EXPECT_TRUE(fs::exists(path("overlays/view1_ap_xray_overlay.png")));
  expect_provenance(result, "register");
  EXPECT_EQ(result["provenance"]["settings"]["iso_hu"], 250.0);
  EXPECT_EQ(result["provenance"]["settings"]["fine_stages"].size(), 3u);
  EXPECT_EQ(result["provenance"]["inputs"].size(), 8u);  // CT, start pose, three X-rays and cameras
  // The ITK transform, read by ITK, is the registered pose's inverse: world (fixed) to CT (moving).
  const Eigen::Matrix4d tfm = test::read_itk_transform(path("r.tfm"));
  EXPECT_LT((tfm - found.inverse().matrix()).cwiseAbs().maxCoeff(), 1e-9);
  // The polish's mode is one of three words; another is refused before any work.
  const CliResult bad = run("register" + views_ + " --init " + path("demo/start_pose.json") +
                            " --polish-correlation=sometimes --out " + path("bad.json"));
  EXPECT_EQ(bad.code, 2);
  EXPECT_NE(bad.err.find("--polish-correlation"), std::string::npos) << bad.err;
  EXPECT_FALSE(fs::exists(path("bad.json")));
}

// The flag alone forces the polish, and =true and =false read as on and off, as when it was a
// plain flag. (Two registrations, one polished: left out of the sanitizer pass.)
TEST_F(CliRegister, ThePolishFlagAloneOrWithAValue) {
  ASSERT_EQ(run("register" + views_ + " --init " + path("demo/start_pose.json") + " --polish-correlation --out " +
                path("polished.json")).code, 0);
  const auto polished = read_json(path("polished.json"));
  EXPECT_EQ(polished["provenance"]["settings"]["correlation_polish"], "on");
  EXPECT_EQ(polished["stages"].back()["name"], "correlation");
  ASSERT_EQ(run("register" + views_ + " --init " + path("demo/start_pose.json") + " --polish-correlation=false --out " +
                path("off.json")).code, 0);
  const auto off = read_json(path("off.json"));
  EXPECT_EQ(off["provenance"]["settings"]["correlation_polish"], "off");
  EXPECT_EQ(off["stages"].size(), 4u);
}

TEST_F(CliRegister, FromLandmarksTriangulatesTheInitialPose) {
  // Four landmarks: CT points and their pixels at the true pose (one hidden in a view).
  const Pose truth = read_pose(path("demo/truth_pose.json"));
  std::vector<PinholeCamera> cams;
  for (const char* v : {"ap", "oblique60", "lateral_tilted"}) cams.push_back(read_camera(path("demo/" + std::string(v) + "_camera.json")));
  nlohmann::json lm = {{"landmarks", nlohmann::json::array()}};
  const Eigen::Vector3d points[] = {{10, 5, 60}, {-15, 0, -50}, {20, -10, -20}, {0, 15, 30}};
  for (int i = 0; i < 4; ++i) {
    nlohmann::json pixels = nlohmann::json::array();
    for (int v = 0; v < 3; ++v) {
      const Eigen::Vector2d uv = cams[size_t(v)].project(truth * points[i]);
      if (i == 0 && v == 1) pixels.push_back(nullptr);
      else pixels.push_back({uv.x() + 0.3, uv.y() - 0.2});
    }
    lm["landmarks"].push_back({{"name", "p" + std::to_string(i)}, {"ct", {points[i].x(), points[i].y(), points[i].z()}},
                               {"pixels", pixels}});
  }
  write_json(lm, path("landmarks.json"));
  const CliResult r = run("register" + views_ + " --landmarks " + path("landmarks.json") + " --out " + path("r.json"));
  ASSERT_EQ(r.code, 0) << r.err;
  const auto result = read_json(path("r.json"));
  EXPECT_EQ(result["initial"]["source"], "landmarks");
  EXPECT_EQ(result["initial"]["landmarks_used"], 4);
  EXPECT_LT(result["initial"]["fre_rms_mm"].get<double>(), 1.0);
  const Pose found = read_pose(path("r.json"));
  EXPECT_LT((found.translation() - truth.translation()).norm(), 1.5);
}

TEST_F(CliRegister, BadInputIsOneLineAndExitCodeTwo) {
  // A camera whose image size disagrees with its X-ray.
  CArmGeometry g;
  g.pixels = 200;
  write_camera(c_arm_view(g, 0), path("small_cam.json"));
  expect_bad_input(run("register" + views_ + " --view " + path("demo/ap_xray.png") + ":" + path("small_cam.json") +
                       " --init " + path("demo/start_pose.json") + " --out " + path("x.json")),
                   "ap_xray.png: the image is 256x256 pixels but its camera");
  // Neither an initial pose nor landmarks; both.
  expect_bad_input(run("register" + views_ + " --out " + path("x.json")), "--init");
  EXPECT_EQ(run("register" + views_ + " --init a.json --landmarks b.json --out " + path("x.json")).code, 2);
  // Too few landmarks.
  write_text("lm.json", R"({"landmarks": [{"ct": [0, 0, 0], "pixels": [[1, 2], [3, 4], null]}]})");
  expect_bad_input(run("register" + views_ + " --landmarks " + path("lm.json") + " --out " + path("x.json")),
                   "lm.json: 1 landmarks seen in two or more views; at least 3 are needed");
  // A CT without bone above the iso-value.
  expect_bad_input(run("register" + views_ + " --init " + path("demo/start_pose.json") + " --iso 5000 --out " + path("x.json")),
                   "CT: no bone");
  expect_bad_input(run("register" + views_ + " --init " + path("demo/start_pose.json") + " --tissue-hu 5000 --out " + path("x.json")),
                   "CT: no voxel above the soft-tissue threshold of 5000 HU");
  expect_bad_input(run("register" + views_ + " --init " + path("demo/start_pose.json") + " --livewire --out " + path("x.json")),
                   "--livewire: needs --contours");
  // One X-ray: the depth is not fixed.
  expect_bad_input(run("register --ct " + path("ct.nii.gz") + " --view " + path("demo/ap_xray.png") + ":" +
                       path("demo/ap_camera.json") + " --init " + path("demo/start_pose.json") + " --out " + path("x.json")),
                   "--view: one X-ray does not fix the depth");
  // Contours outside the image.
  write_text("c.json", R"({"views": [{"polylines": [[[10, 10], [900, 10]]]}, {}, {}]})");
  expect_bad_input(run("register" + views_ + " --init " + path("demo/start_pose.json") + " --contours " + path("c.json") +
                       " --out " + path("x.json")),
                   "c.json: view 1: point (900");
  EXPECT_FALSE(fs::exists(path("x.json")));
}

TEST_F(Cli, SweepWritesRowsResumesAndPlots) {
  write_text("sweep.json", R"({"phantom": {"kind": "femur", "size": 64}, "c_arm": {"pixels": 192, "pixel_mm": 1.6},
    "distances_mm": {"from": 3, "to": 8, "step": 5}, "runs_per_distance": 2, "contours": "automatic"})");
  const CliResult r = run("sweep --config " + path("sweep.json") + " --out " + path("runs.csv") + " --plot " + path("plot.svg"));
  ASSERT_EQ(r.code, 0) << r.err;
  std::string csv = slurp(path("runs.csv"));
  EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 5) << csv;  // header + 4 runs
  EXPECT_NE(slurp(path("plot.svg")).find("<svg"), std::string::npos);
  EXPECT_NE(r.out.find("4 runs, 100.0% success"), std::string::npos) << r.out;
  // The per-distance summary beside the runs file: two bins of two runs, then the whole sweep.
  const std::string summary = slurp(path("runs_summary.csv"));
  EXPECT_EQ(std::count(summary.begin(), summary.end(), '\n'), 4) << summary;
  EXPECT_NE(summary.find("\n3.000000,2,2,100.00,0,"), std::string::npos) << summary;
  EXPECT_NE(summary.find("\nall,4,4,100.00,0,"), std::string::npos) << summary;
  EXPECT_NE(r.out.find("false_confident"), std::string::npos) << r.out;
  // Every run measured its confidence check: finite sharpness, offset and relative correlation in
  // each row (the last three fields), and the successes' margin in the summary (least sharpness,
  // largest offset, least relative correlation), none of the failures'.
  {
    std::istringstream rows(csv);
    std::string line;
    std::getline(rows, line);
    EXPECT_NE(line.find(",min_view_correlation,min_sharpness,max_peak_offset,relative_correlation"), std::string::npos) << line;
    while (std::getline(rows, line)) {
      const size_t last = line.rfind(','), before = line.rfind(',', last - 1), first = line.rfind(',', before - 1);
      const double sharpness = std::stod(line.substr(first + 1, before - first - 1));
      const double offset = std::stod(line.substr(before + 1, last - before - 1));
      const double relative = std::stod(line.substr(last + 1));
      EXPECT_TRUE(std::isfinite(sharpness) && sharpness > 0) << line;  // every run here succeeds
      EXPECT_TRUE(std::isfinite(offset) && offset >= 0) << line;
      EXPECT_GT(relative, 0.45) << line;  // clean DRRs of the CT: about 1
    }
    const size_t all = summary.find("\nall,");
    ASSERT_NE(all, std::string::npos);
    const std::string all_line = summary.substr(all + 1, summary.find('\n', all + 1) - all - 1);
    // The successes' margins there; no failure, so the failures' are empty.
    std::vector<std::string> f;
    std::istringstream fields(all_line + ",");
    for (std::string v; std::getline(fields, v, ',');) f.push_back(v);
    ASSERT_EQ(f.size(), 14u) << all_line;
    EXPECT_FALSE(f[8].empty() || f[9].empty()) << all_line;  // least sharpness, largest offset
    EXPECT_TRUE(f[10].empty() && f[11].empty() && f[13].empty()) << all_line;
    ASSERT_FALSE(f[12].empty()) << all_line;  // least relative correlation
    EXPECT_GT(std::stod(f[12]), 0.45) << all_line;
  }
  // Resume: a finished sweep runs nothing; a row cut short by a crash is dropped and redone.
  const CliResult again = run("sweep --config " + path("sweep.json") + " --out " + path("runs.csv"));
  EXPECT_NE(again.err.find("4 already in"), std::string::npos) << again.err;
  csv.resize(csv.size() - 20);
  write_text("runs.csv", csv);
  const CliResult resumed = run("sweep --config " + path("sweep.json") + " --out " + path("runs.csv"));
  ASSERT_EQ(resumed.code, 0) << resumed.err;
  EXPECT_NE(resumed.err.find("3 already in"), std::string::npos) << resumed.err;
  const std::string after = slurp(path("runs.csv"));
  EXPECT_EQ(std::count(after.begin(), after.end(), '\n'), 5) << after;
  // A runs file of the former format (before the sharpness and relative columns) resumes: its rows
  // are kept, rewritten with those three columns unmeasured.
  {
    std::istringstream rows(after);
    std::string former, line;
    while (std::getline(rows, line)) {
      for (int cut = 0; cut < 3; ++cut) line.resize(line.rfind(','));
      former += line + "\n";
    }
    write_text("runs.csv", former);
    const CliResult old = run("sweep --config " + path("sweep.json") + " --out " + path("runs.csv"));
    ASSERT_EQ(old.code, 0) << old.err;
    EXPECT_NE(old.err.find("4 already in"), std::string::npos) << old.err;
    const std::string rewritten = slurp(path("runs.csv"));
    EXPECT_NE(rewritten.find(",min_sharpness,max_peak_offset,relative_correlation\n"), std::string::npos) << rewritten;
    EXPECT_EQ(std::count(rewritten.begin(), rewritten.end(), '\n'), 5) << rewritten;
    size_t unmeasured = 0;
    for (size_t at = rewritten.find(",nan,nan,nan\n"); at != std::string::npos; at = rewritten.find(",nan,nan,nan\n", at + 1))
      ++unmeasured;
    EXPECT_EQ(unmeasured, 4u) << rewritten;
  }
  // One of the sharpness header (2026-12-03 to 04, before relative_correlation) resumes too: its
  // sharpness is kept, its relative correlation unmeasured.
  {
    std::istringstream rows(after);
    std::string sharpness_only, line;
    while (std::getline(rows, line)) {
      line.resize(line.rfind(','));
      sharpness_only += line + "\n";
    }
    write_text("fresh.csv", sharpness_only);
    const CliResult old = run("sweep --config " + path("sweep.json") + " --out " + path("fresh.csv"));
    ASSERT_EQ(old.code, 0) << old.err;
    EXPECT_NE(old.err.find("4 already in"), std::string::npos) << old.err;
    const std::string rewritten = slurp(path("fresh.csv"));
    std::istringstream again(rewritten);
    std::getline(again, line);
    const std::string tail = ",min_sharpness,max_peak_offset,relative_correlation";
    EXPECT_EQ(line.rfind(tail), line.size() - tail.size()) << line;
    int kept = 0;
    while (std::getline(again, line)) {
      const size_t last = line.rfind(','), before = line.rfind(',', last - 1);
      EXPECT_EQ(line.substr(last), ",nan") << line;
      kept += std::isfinite(std::stod(line.substr(before + 1, last - before - 1)));  // the sharpness's offset
    }
    EXPECT_EQ(kept, 4) << rewritten;
  }
  // Another sweep's file is refused.
  write_text("other.json", R"({"phantom": {"kind": "femur", "size": 64}, "distances_mm": {"from": 4, "to": 4}, "runs_per_distance": 4})");
  expect_bad_input(run("sweep --config " + path("other.json") + " --out " + path("runs.csv")), "runs.csv: holds runs");
}

}  // namespace
}  // namespace fluoro
