// Inputs the fuzz targets (fuzz/, docs/fuzzing.md) found crashing or breaking the error contract,
// kept in tests/fuzz_regressions/<target>/ and read here with that target's reader: each must give
// a result or an InputError of one line naming the file, in the normal (and the sanitizer) build.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <map>
#include <string>

#include "engine/distal_locking_models.hpp"
#include "engine/error.hpp"
#include "engine/grid_model.hpp"
#include "engine/image_io.hpp"
#include "engine/json_io.hpp"
#include "engine/mesh_format_readers.hpp"
#include "engine/phantom_model.hpp"
#include "engine/point_list_io.hpp"
#include "engine/pose_list_io.hpp"
#include "engine/volume_io.hpp"
#include "pipelines/registration/landmarks.hpp"
#include "pipelines/registration/registration_io.hpp"
#include "pipelines/sweep/sweep.hpp"

namespace fluoro {
namespace {

namespace fs = std::filesystem;

std::string slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// Runs read(path); an InputError must be one line naming the file.
void expect_read_or_one_line(const std::string& path, const std::function<void(const std::string&)>& read) {
  try {
    read(path);
  } catch (const InputError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find(path), std::string::npos) << message;
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;
  }
}

// The volume formats' targets give each input to both readers that take such a name.
void volume_then_image(const std::string& path) {
  expect_read_or_one_line(path, [](const std::string& p) { read_volume(p); });
  expect_read_or_one_line(path, [](const std::string& p) { read_image(p); });
}

// The reader of each fuzz target (fuzz/fuzz_<target>.cpp), by target name.
const std::map<std::string, std::function<void(const std::string&)>>& readers() {
  static const std::map<std::string, std::function<void(const std::string&)>> r = {
      {"volume_nii", volume_then_image},
      {"volume_mha", volume_then_image},
      {"volume_nrrd", volume_then_image},
      {"volume_dcm", [](const std::string& p) { read_volume(p); }},
      {"image_png", [](const std::string& p) { read_image(p); }},
      {"image_tif", [](const std::string& p) { read_image(p); }},
      {"image_pfm", [](const std::string& p) { read_image(p); }},
      {"mesh_stl", [](const std::string& p) { mesh_detail::read_stl(slurp(p), p); }},
      {"mesh_ply", [](const std::string& p) { mesh_detail::read_ply(slurp(p), p); }},
      {"mesh_obj", [](const std::string& p) { mesh_detail::read_obj(slurp(p), p); }},
      {"camera", [](const std::string& p) { read_camera(p); }},
      {"pose", [](const std::string& p) { read_pose(p); }},
      {"pose_list", [](const std::string& p) { read_pose_list(p); }},
      {"points", [](const std::string& p) { read_points_3d(p); }},
      {"grid", [](const std::string& p) { read_grid_model(p); }},
      {"phantom", [](const std::string& p) { read_phantom_model(p); }},
      {"guide", [](const std::string& p) { read_drill_guide_model(p); }},
      {"nail", [](const std::string& p) { read_nail_model(p); }},
      {"robot", [](const std::string& p) { read_robot_model(p); }},
      {"landmarks", [](const std::string& p) { read_landmarks(p, 2); }},
      {"contours", [](const std::string& p) { read_contours(p, {64, 48}, {48, 64}); }},
      {"sweep_config", [](const std::string& p) { read_sweep_config(p); }},
  };
  return r;
}

// The readers pick the format by the file's name, as the fuzz targets' files are named.
std::string extension_of(const std::string& target) {
  if (target.rfind("volume_", 0) == 0 || target.rfind("image_", 0) == 0 || target.rfind("mesh_", 0) == 0)
    return "." + target.substr(target.find('_') + 1);
  return ".json";
}

TEST(FuzzRegressions, EveryKeptInputIsReadOrRefusedInOneLine) {
  const fs::path root = fs::path(FLUORO_SOURCE_DIR) / "tests" / "fuzz_regressions";
  const fs::path work = fs::temp_directory_path() / ("fluoro_fuzz_regressions_" + std::to_string(::getpid()));
  fs::create_directories(work);
  int inputs = 0;
  for (const auto& dir : fs::directory_iterator(root)) {
    const std::string target = dir.path().filename().string();
    ASSERT_TRUE(readers().count(target)) << "no reader for " << target;
    for (const auto& file : fs::directory_iterator(dir.path())) {
      SCOPED_TRACE(file.path().string());
      const std::string path = (work / (file.path().filename().string() + extension_of(target))).string();
      fs::copy_file(file.path(), path, fs::copy_options::overwrite_existing);
      expect_read_or_one_line(path, readers().at(target));
      ++inputs;
    }
  }
  fs::remove_all(work);
  EXPECT_GT(inputs, 0) << "tests/fuzz_regressions/ is empty";
}

}  // namespace
}  // namespace fluoro
