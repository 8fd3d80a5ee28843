// fluoro info FILE: the header of a volume, an image, or a camera/pose JSON.
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <string>

#include "apps/fluoro/commands.hpp"
#include "engine/error.hpp"
#include "engine/file_names.hpp"
#include "engine/image_io.hpp"
#include "engine/json_io.hpp"
#include "engine/volume_io.hpp"

namespace fluoro::cli {
namespace {

bool is_volume_path(const std::string& p) { return is_volume_file_name(p) || std::filesystem::is_directory(p); }

template <class T, class A>
std::pair<double, double> value_range(const std::vector<T, A>& v) {
  if (v.empty()) return {0, 0};
  auto [lo, hi] = std::minmax_element(v.begin(), v.end());
  return {double(*lo), double(*hi)};
}

void print_volume(const std::string& path) {
  const Volume v = read_volume(path);
  const auto& g = v.geometry;
  const auto [lo, hi] = value_range(v.voxels);
  std::printf("%s: volume\n", path.c_str());
  std::printf("  size       %d x %d x %d voxels\n", g.size.x(), g.size.y(), g.size.z());
  std::printf("  spacing    %.6g %.6g %.6g mm\n", g.spacing.x(), g.spacing.y(), g.spacing.z());
  std::printf("  origin     %.6g %.6g %.6g mm\n", g.origin.x(), g.origin.y(), g.origin.z());
  std::printf("  direction  [%.6g %.6g %.6g; %.6g %.6g %.6g; %.6g %.6g %.6g] (columns: i, j, k axes)\n",
              g.direction(0, 0), g.direction(0, 1), g.direction(0, 2), g.direction(1, 0),
              g.direction(1, 1), g.direction(1, 2), g.direction(2, 0), g.direction(2, 1),
              g.direction(2, 2));
  std::printf("  extent     %.6g x %.6g x %.6g mm\n", g.size.x() * g.spacing.x(),
              g.size.y() * g.spacing.y(), g.size.z() * g.spacing.z());
  std::printf("  values     %.6g to %.6g\n", lo, hi);
}

void print_image(const std::string& path) {
  const Image im = read_image(path);
  const auto [lo, hi] = value_range(im.pixels);
  std::printf("%s: image\n  size       %d x %d pixels\n  values     %.6g to %.6g\n", path.c_str(),
              im.width, im.height, lo, hi);
}

void print_json(const std::string& path) {
  const nlohmann::json j = read_json(path);
  if (j.contains("T_world_ct")) {
    const Pose p = read_pose(path);
    std::printf("%s: pose T_world_ct\n  rotation   %.6g deg\n  translation %.6g %.6g %.6g mm\n",
                path.c_str(), rotation_angle_deg(p), p.translation().x(), p.translation().y(),
                p.translation().z());
    return;
  }
  const PinholeCamera c = read_camera(path);
  const Eigen::Vector3d s = c.source();
  std::printf("%s: camera\n  size       %d x %d pixels\n  focal      %.6g, %.6g px, principal point %.6g, %.6g\n"
              "  source     %.6g %.6g %.6g mm (world)\n",
              path.c_str(), c.width, c.height, c.K(0, 0), c.K(1, 1), c.K(0, 2), c.K(1, 2), s.x(),
              s.y(), s.z());
}

}  // namespace

void add_info_command(CLI::App& app) {
  auto* cmd = app.add_subcommand("info", "Print the header of a volume, an image, or a camera/pose JSON");
  auto path = std::make_shared<std::string>();
  cmd->add_option("FILE", *path,
                  "Volume (.nii, .nii.gz, .mha, .mhd, .nrrd, .nhdr, DICOM directory), image (PNG, TIFF, JPEG, BMP, "
                  "DICOM, PFM, or a 2D file by a volume's names), or JSON")
      ->required();
  cmd->callback([path] {
    if (!std::filesystem::exists(*path)) throw_input_error(*path, "no such file or directory");
    if (ends_with(*path, ".json")) print_json(*path);
    // A 2D file by a volume's name (a DRR `fluoro drr` wrote as .nii, .mha or .nrrd) is an image.
    else if (is_volume_path(*path) && (std::filesystem::is_directory(*path) || !is_2d_image_file(*path)))
      print_volume(*path);
    else print_image(*path);
  });
}

}  // namespace fluoro::cli
