// Prepared CT files (fluoro prepare, register/sweep --prepared): a registration from a prepared
// file gives the pose of one that prepares the CT itself, bit for bit, and every way a prepared
// file can be wrong (another CT, other settings, another version, cut short, a flipped byte,
// another backend) is refused with one line and exit 2.
#include <zlib.h>

#include <cstdio>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>

#include "datasets/c_arm.hpp"
#include "datasets/phantom.hpp"
#include "engine/attenuation.hpp"
#include "engine/backend.hpp"
#include "engine/json_io.hpp"
#include "engine/pose.hpp"
#include "engine/volume_io.hpp"
#include "engine/pose_list_io.hpp"
#include "kernels/backend_registry.hpp"
#include "kernels/cpu/cpu_volume.hpp"
#include "pipelines/registration/prepared_ct.hpp"
#include "pipelines/registration/registration.hpp"
#include "tests/cli_fixture.hpp"

namespace fluoro {
namespace {

namespace fs = std::filesystem;

std::vector<uint8_t> read_bytes(const std::string& p) {
  std::ifstream f(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(f), {}};
}

void write_bytes(const std::string& p, const std::vector<uint8_t>& b) {
  std::ofstream(p, std::ios::binary).write(reinterpret_cast<const char*>(b.data()), std::streamsize(b.size()));
}

// Rewrites the trailer's CRC-32 after an edit, so that the edit itself is what is checked.
void reseal(std::vector<uint8_t>& b) {
  const uint32_t crc = uint32_t(crc32(crc32(0L, Z_NULL, 0), b.data(), uInt(b.size() - 8)));
  std::memcpy(b.data() + b.size() - 8, &crc, 4);
}

// Every word and brick distance of a cpu volume, for exact comparisons.
std::vector<uint64_t> words_of(const DeviceVolume& v) {
  const cpu::PaddedGrid g = static_cast<const cpu::CpuVolume&>(v).grid();
  return {g.words, g.words + size_t(g.nx) * size_t(g.ny) * size_t(g.nz)};
}

TEST(PreparedCt, CpuVolumesSaveAndLoadBitForBit) {
  auto backend = make_backend("cpu");
  // Odd sizes (padding and partial bricks), signed and unsigned data, a hollow so some bricks are
  // empty; fine voxels (bricks of 4^3) and coarse ones (2^3).
  for (const double scale : {1.0, 4.0}) {
    SCOPED_TRACE(scale);
    Volume mu;
    mu.geometry.size = {13, 9, 7};
    mu.geometry.spacing = Eigen::Vector3d(0.7, 1.1, 1.9) * scale;
    mu.voxels.resize(mu.geometry.voxel_count());
    std::mt19937 rng(3);
    std::uniform_real_distribution<float> u(0.0f, 0.05f);
    for (int k = 0; k < 7; ++k)
      for (int j = 0; j < 9; ++j)
        for (int i = 0; i < 13; ++i) mu.at(i, j, k) = i < 6 ? 0.0f : u(rng);
    const auto scalar = backend->upload(mu);
    const auto field = backend->gradient_field(*scalar, {1.0, 0.0});
    for (const auto& v : {scalar, field}) {
      const std::vector<uint8_t> bytes = backend->save_volume(*v);
      const auto loaded = backend->load_volume(v->geometry(), v->components(), bytes, "test");
      EXPECT_EQ(words_of(*loaded), words_of(*v));
      const cpu::PaddedGrid a = static_cast<const cpu::CpuVolume&>(*v).grid(), b = static_cast<const cpu::CpuVolume&>(*loaded).grid();
      const size_t bricks = size_t(a.bricks_x) * size_t(a.bricks_y) * size_t((a.nz + (1 << a.brick_shift) - 1) >> a.brick_shift);
      EXPECT_TRUE(std::equal(a.occupancy, a.occupancy + bricks, b.occupancy));
      EXPECT_EQ(std::memcmp(a.scale, b.scale, sizeof a.scale), 0);
      EXPECT_EQ(a.is_signed, b.is_signed);
      // Bytes that do not fit the geometry are bad input.
      EXPECT_THROW(backend->load_volume(v->geometry(), v->components(), std::span(bytes).first(bytes.size() - 8), "test"),
                   InputError);
      EXPECT_EQ(a.brick_shift, scale == 1.0 ? 2 : 1);
    }
    if (scale == 1.0) continue;
    // Backends without a saved form say so.
    auto reference = make_backend("reference");
    EXPECT_FALSE(reference->can_save_volumes());
    EXPECT_THROW(reference->save_volume(*reference->upload(mu)), BackendUnavailable);
  }
}

// Bone and the rest add up to the whole CT: DRRs of bone_mu plus non_bone_mu are DRRs of the CT's
// attenuation, also where the rest is kept on a coarser grid: voxels of 0.5 x 0.7 x 0.4 mm,
// box-averaged by 3 x 2 x 4 (97 voxels a side: partial blocks at the far faces).
TEST(PreparedCt, BoneAndTheRestAddUpToTheWholeCt) {
  auto backend = make_backend("cpu");
  PhantomParams pp;
  pp.size = 97;
  pp.fov_mm = 48;
  Volume hu = make_phantom(pp).hu;
  hu.geometry.spacing = Eigen::Vector3d(0.5, 0.7, 0.4);
  hu.geometry.origin = -0.5 * hu.geometry.spacing * 96.0;
  const RegistrationOptions options;
  const PreparedCt p = prepare_ct(*backend, hu, options, nullptr);
  EXPECT_TRUE(p.non_bone_mu->geometry().spacing.isApprox(Eigen::Vector3d(1.5, 1.4, 1.6), 1e-9));
  EXPECT_EQ(p.non_bone_mu->geometry().size, Eigen::Vector3i(33, 49, 25));
  EXPECT_TRUE(p.bone_mu->geometry().spacing.isApprox(hu.geometry.spacing, 1e-9));
  const auto whole = backend->upload(hu_to_attenuation(hu, {options.mu_water_per_mm}));
  CArmGeometry g;
  g.pixels = 128;
  g.pixel_mm = 0.6;
  const std::vector<PinholeCamera> cams = {c_arm_view(g, 0), c_arm_view(g, 70, 20)};
  const Pose at = pose_from_rotation_vector(Eigen::Vector3d(0.1, -0.2, 0.3), Eigen::Vector3d(1, 2, -1));
  const DrrParams step{0.25, {}};
  const auto bone = backend->drr(*p.bone_mu, std::span(&at, 1), cams, step);
  const auto rest = backend->drr(*p.non_bone_mu, std::span(&at, 1), cams, step);
  const auto all = backend->drr(*whole, std::span(&at, 1), cams, step);
  for (size_t v = 0; v < cams.size(); ++v) {
    double sum_all = 0, sum_parts = 0, squared = 0, bone_sum = 0, all_squared = 0;
    for (size_t i = 0; i < all[v].pixels.size(); ++i) {
      const double parts = double(bone[v].pixels[i]) + rest[v].pixels[i];
      sum_all += all[v].pixels[i];
      sum_parts += parts;
      bone_sum += bone[v].pixels[i];
      squared += (parts - all[v].pixels[i]) * (parts - all[v].pixels[i]);
      all_squared += double(all[v].pixels[i]) * all[v].pixels[i];
    }
    std::printf("view %zu: bone %.3f of the whole; parts/whole %.5f; RMS difference %.4f of the RMS\n", v,
                bone_sum / sum_all, sum_parts / sum_all, std::sqrt(squared / all_squared));
    EXPECT_GT(bone_sum, 0.02 * sum_all) << "the view sees bone";
    EXPECT_NEAR(sum_parts / sum_all, 1.0, 0.01) << "view " << v;
    EXPECT_LT(std::sqrt(squared / all_squared), 0.04) << "view " << v;  // 0.031-0.034; the coarse grid half a fine voxel to a voxel and a half off: 0.07-0.09
  }
}

// One scene for the suite: the 64^3 femur phantom, three 256^2 views and its prepared file.
class PreparedCtCli : public test::CliTest {
 protected:
  static void SetUpTestSuite() {
    scene_ = fs::temp_directory_path() / ("fluoro_prepared_" + std::to_string(::getpid()));
    fs::remove_all(scene_);
    fs::create_directories(scene_);
    auto fluoro = [](const std::string& args) {
      return std::system((std::string(FLUORO_CLI) + " -q " + args + " >/dev/null 2>&1").c_str());
    };
    // The demo's scene without the demo's own registration: three 256^2 C-arm views of the
    // phantom centred at the isocentre, rendered by `fluoro drr`, and a start 2.5 degrees and
    // 3.7 mm off.
    ASSERT_EQ(fluoro("phantom --kind femur --size 64 --out " + at("ct.nii.gz")), 0);
    const Eigen::Vector3d centre = read_volume(at("ct.nii.gz")).geometry.physical_centre();
    write_pose(pose_from_rotation_vector(Eigen::Vector3d::Zero(), -centre), at("truth.json"));
    const Pose turn = pose_from_rotation_vector(Eigen::Vector3d(0.02, -0.03, 0.025), Eigen::Vector3d(2, -2.5, 1.5));
    write_pose(turn * pose_from_rotation_vector(Eigen::Vector3d::Zero(), -centre), at("start.json"));
    CArmGeometry g;
    g.pixels = 256;
    g.pixel_mm = 1.6;
    const std::pair<const char*, std::pair<double, double>> views[] = {{"ap", {0, 0}}, {"oblique60", {60, 0}},
                                                                       {"lateral_tilted", {100, 15}}};
    for (const auto& [name, angles] : views) {
      write_camera(c_arm_view(g, angles.first, angles.second), at(std::string(name) + "_camera.json"));
      ASSERT_EQ(fluoro("drr --ct " + at("ct.nii.gz") + " --camera " + at(std::string(name) + "_camera.json") +
                       " --pose " + at("truth.json") + " --out " + at(std::string(name) + "_xray.png")),
                0);
    }
    ASSERT_EQ(fluoro("prepare --ct " + at("ct.nii.gz") + " --out " + at("ct.fluoroprep")), 0);
  }
  static void TearDownTestSuite() { fs::remove_all(scene_); }
  static std::string at(const std::string& name) { return (scene_ / name).string(); }
  static std::string views() {
    std::string v;
    for (const char* name : {"ap", "oblique60", "lateral_tilted"})
      v += " --view " + at(std::string(name) + "_xray.png") + ":" + at(std::string(name) + "_camera.json");
    return v + " --init " + at("start.json");
  }
  // `register` of the scene's CT with a prepared file and extra arguments.
  test::CliResult register_with(const std::string& prepared, const std::string& extra = "") const {
    return run("register --ct " + at("ct.nii.gz") + views() + " --prepared " + prepared + extra + " --out " + path("r.json"));
  }
  static fs::path scene_;
};
fs::path PreparedCtCli::scene_;

TEST_F(PreparedCtCli, RegisterGivesTheSamePoseAsWithoutAndRecordsTheFile) {
  const test::CliResult plain = run("register --ct " + at("ct.nii.gz") + views() + " --out " + path("plain.json"));
  ASSERT_EQ(plain.code, 0) << plain.err;
  const test::CliResult prepared = register_with(at("ct.fluoroprep"));
  ASSERT_EQ(prepared.code, 0) << prepared.err;
  const nlohmann::json a = read_json(path("plain.json")), b = read_json(path("r.json"));
  // Identical fields and mesh: the pose, scores and correlations to the last bit (17 digits), and
  // every stage the same number of evaluations.
  ASSERT_TRUE(a["T_world_ct"].is_array());
  EXPECT_EQ(a["T_world_ct"], b["T_world_ct"]);
  EXPECT_EQ(a["score"], b["score"]);
  EXPECT_EQ(a["view_gradient_correlations"], b["view_gradient_correlations"]);
  // A 4 mm CT in views of 1.6 mm pixels correlates far lower than the 128^3 phantoms do (about
  // 0.26), yet as much as an X-ray of the whole CT predicts: confident under the relative floor.
  std::printf("correlation %.3f, expected %.3f, relative %.3f\n", a["gradient_correlation"].get<double>(),
              a["confidence"]["expected_correlation"].get<double>(), a["confidence"]["relative_correlation"].get<double>());
  EXPECT_LT(a["gradient_correlation"].get<double>(), 0.35);
  EXPECT_NEAR(a["confidence"]["relative_correlation"].get<double>(), 1.0, 0.15);
  EXPECT_TRUE(a["confidence"]["relative_correlation_floor_met"].get<bool>());
  EXPECT_TRUE(a["confident"].get<bool>());
  EXPECT_EQ(a["confidence"]["expected_correlation"], b["confidence"]["expected_correlation"]);
  ASSERT_EQ(a["stages"].size(), 4u);
  ASSERT_EQ(b["stages"].size(), 4u);
  for (size_t i = 0; i < 4; ++i) {
    EXPECT_EQ(a["stages"][i]["evaluations"], b["stages"][i]["evaluations"]) << i;
    EXPECT_EQ(a["stages"][i]["iterations"], b["stages"][i]["iterations"]) << i;
  }
  expect_provenance(b, "register");
  EXPECT_EQ(b["inputs"]["prepared"]["path"], at("ct.fluoroprep"));
  EXPECT_EQ(b["provenance"]["settings"]["ct_preparation"], "prepared file");
  bool recorded = false;
  for (const auto& f : b["provenance"]["inputs"])
    recorded = recorded || (f["path"] == at("ct.fluoroprep") && f["sha256"] == sha256_file(at("ct.fluoroprep")));
  EXPECT_TRUE(recorded);
  EXPECT_GE(b["prepared_load_seconds"].get<double>(), 0.0);
}

// One test for every refusal: ctest runs each test in a process of its own, which makes the
// suite's scene again (about 1.3 s of CPU).
TEST_F(PreparedCtCli, WrongOrDamagedFilesAreRefused) {
  // Another CT (the same phantom, another seed): both files named.
  ASSERT_EQ(run("phantom --kind femur --size 64 --seed 7 --out " + path("other.nii.gz")).code, 0);
  const test::CliResult other = run("register --ct " + path("other.nii.gz") + views() + " --prepared " +
                                    at("ct.fluoroprep") + " --out " + path("r.json"));
  expect_bad_input(other, "ct.fluoroprep: prepared from CT " + at("ct.nii.gz") + " (sha256 ", "r.json");
  EXPECT_NE(other.err.find("not from " + path("other.nii.gz") + " (sha256 "), std::string::npos) << other.err;
  // Other settings: which one, and how to prepare again.
  expect_bad_input(register_with(at("ct.fluoroprep"), " --tissue-hu 150"), "other settings than this run's (tissue_hu 100.0 against 150.0)", "r.json");
  expect_bad_input(register_with(at("ct.fluoroprep"), " --mask " + at("ct.nii.gz")), "prepared without a bone mask", "r.json");
  // Another backend, and a backend that cannot prepare.
  expect_bad_input(register_with(at("ct.fluoroprep"), " --backend reference"), "prepared for the cpu backend, this run uses reference", "r.json");
  expect_bad_input(run("prepare --ct " + at("ct.nii.gz") + " --backend reference --out " + path("p.fluoroprep")),
                   "reference backend cannot save", "p.fluoroprep");
  // Not a prepared file at all.
  expect_bad_input(register_with(at("ct.nii.gz")), "not a prepared CT file", "r.json");

  const std::vector<uint8_t> good = read_bytes(at("ct.fluoroprep"));
  ASSERT_GT(good.size(), 1000u);
  // An older format version.
  std::vector<uint8_t> b = good;
  b[8] = 0;
  write_bytes(path("old_format.fluoroprep"), b);
  expect_bad_input(register_with(path("old_format.fluoroprep")), "prepared file format version 0, this fluoro", "r.json");
  // Another program version, checksum intact.
  b = good;
  const std::string version = std::string("\"version\":\"") + FLUORO_VERSION + "\"";
  const auto at_version = std::search(b.begin(), b.end(), version.begin(), version.end());
  ASSERT_NE(at_version, b.end());
  *(at_version + long(version.size()) - 2) = '~';  // "0.1.0" -> "0.1.~"
  reseal(b);
  write_bytes(path("old_program.fluoroprep"), b);
  expect_bad_input(register_with(path("old_program.fluoroprep")), "prepared by fluoro ", "r.json");
  // Prepared before fields kept the CT's coarser axes (no such settings key): prepare again.
  b = good;
  const std::string key = "\"field_axes_coarser_than_grid\"";
  const auto at_key = std::search(b.begin(), b.end(), key.begin(), key.end());
  ASSERT_NE(at_key, b.end());
  *(at_key + 1) = 'x';  // another key of the same length, so every offset stays
  reseal(b);
  write_bytes(path("older_fields.fluoroprep"), b);
  expect_bad_input(register_with(path("older_fields.fluoroprep")),
                   "prepared by an older version of this program, whose fields' grids differ: prepare it again", "r.json");
  // Cut short.
  b.assign(good.begin(), good.begin() + long(good.size() / 2));
  write_bytes(path("short.fluoroprep"), b);
  expect_bad_input(register_with(path("short.fluoroprep")), "short.fluoroprep: truncated: ", "r.json");
  // One flipped bit in a gradient field.
  b = good;
  b[good.size() - good.size() / 5] ^= 0x10;
  write_bytes(path("flipped.fluoroprep"), b);
  expect_bad_input(register_with(path("flipped.fluoroprep")), "corrupt: its checksum does not match", "r.json");

  // prepare itself: bad input writes nothing, not even a temporary.
  expect_bad_input(run("prepare --ct " + path("missing.nii.gz") + " --out " + path("p.fluoroprep")), "missing.nii.gz", "p.fluoroprep");
  expect_bad_input(run("prepare --ct " + at("ct.nii.gz") + " --tissue-hu 5000 --out " + path("p.fluoroprep")),
                   "no voxel above the soft-tissue threshold", "p.fluoroprep");
  for (const auto& e : fs::directory_iterator(dir_)) {
    const std::string name = e.path().filename().string();  // temporaries keep the stem and extension
    EXPECT_FALSE(name.rfind("p", 0) == 0 && name.find("fluoroprep") != std::string::npos) << name;
  }
}

// `--relative-correlation-floor` sets the floor the result is judged against (0: off), and a
// fraction above 1 is refused as bad input.
TEST_F(PreparedCtCli, TheRelativeCorrelationFloorIsTheCommandsToSet) {
  const test::CliResult off = register_with(at("ct.fluoroprep"), " --relative-correlation-floor 0");
  ASSERT_EQ(off.code, 0) << off.err;
  const nlohmann::json r = read_json(path("r.json"));
  EXPECT_EQ(r["confidence"]["relative_correlation_floor"].get<double>(), 0.0);
  EXPECT_TRUE(r["confidence"]["relative_correlation_floor_met"].get<bool>());
  EXPECT_GT(r["confidence"]["relative_correlation"].get<double>(), 0.8) << "still measured and reported";
  fs::remove(path("r.json"));
  const test::CliResult bad = register_with(at("ct.fluoroprep"), " --relative-correlation-floor 1.5");
  EXPECT_EQ(bad.code, 2);
  EXPECT_NE(bad.err.find("--relative-correlation-floor"), std::string::npos) << bad.err;
  EXPECT_FALSE(fs::exists(path("r.json")));
}

TEST_F(PreparedCtCli, SweepFromAPreparedCtGivesTheSameRows) {
  const std::string config = R"("c_arm": {"pixels": 192, "pixel_mm": 1.6}, "distances_mm": {"from": 4, "to": 4},
    "runs_per_distance": 1, "contours": "traced")";
  write_text("plain.json", "{\"ct\": \"" + at("ct.nii.gz") + "\", " + config + "}");
  write_text("prepared.json", "{\"ct\": \"" + at("ct.nii.gz") + "\", \"prepared\": \"" + at("ct.fluoroprep") + "\", " + config + "}");
  ASSERT_EQ(run("sweep --config " + path("plain.json") + " --out " + path("plain.csv")).code, 0);
  const test::CliResult r = run("sweep --config " + path("prepared.json") + " --out " + path("prepared.csv"));
  ASSERT_EQ(r.code, 0) << r.err;
  // The same rows but for the timing columns.
  auto errors = [](const std::string& csv) {
    std::vector<std::string> cells;
    std::stringstream rows(csv);
    std::string line;
    std::getline(rows, line);
    std::getline(rows, line);
    std::stringstream s(line);
    for (std::string c; std::getline(s, c, ',');) cells.push_back(c);
    return std::vector<std::string>(cells.begin(), cells.begin() + 14);  // run .. gradient_correlation
  };
  EXPECT_EQ(errors(slurp(path("prepared.csv"))), errors(slurp(path("plain.csv"))));
  // A phantom sweep has no CT file to check a prepared one against.
  write_text("phantom.json", R"({"phantom": {"kind": "femur", "size": 64}, "distances_mm": {"from": 4, "to": 4}, "runs_per_distance": 1})");
  expect_bad_input(run("sweep --config " + path("phantom.json") + " --prepared " + at("ct.fluoroprep") + " --out " + path("p.csv")),
                   "ct.fluoroprep: a prepared CT needs the sweep's \"ct\"", "p.csv");
}

}  // namespace
}  // namespace fluoro
