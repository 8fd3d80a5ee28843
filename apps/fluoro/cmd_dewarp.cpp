// fluoro dewarp fit | apply: fit a distortion map to a grid X-ray (MAP.json), and correct images or
// point lists with it (shared/docs/FORMATS.md "Distortion correction"; docs/calibration.md).
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <opencv2/imgproc.hpp>
#include <string>

#include "apps/fluoro/commands.hpp"
#include "apps/fluoro/global_options.hpp"
#include "apps/fluoro/provenance.hpp"
#include "apps/fluoro/result_files.hpp"
#include "engine/atomic_file.hpp"
#include "engine/error.hpp"
#include "engine/file_names.hpp"
#include "engine/grid_model.hpp"
#include "engine/image_io.hpp"
#include "engine/json_io.hpp"
#include "engine/point_list_io.hpp"
#include "pipelines/calibration/dewarp_fit.hpp"

namespace fluoro::cli {
namespace {

struct FitOptions {
  std::string image, grid, out, overlay, model = "polynomial";
};

struct ApplyOptions {
  std::string map, in, points, out;
};



// The grid image, grey levels stretched between its 1st and 99th percentiles, used holes green and
// blobs left out red.
void write_overlay(const Image& image, const DewarpFit& fit, const std::string& path) {
  std::vector<float> v = image.pixels;
  std::sort(v.begin(), v.end());
  const float lo = v[v.size() / 100], hi = std::max(v[v.size() * 99 / 100], lo + 1e-6f);
  cv::Mat rgb(image.height, image.width, CV_8UC3);
  for (int y = 0; y < image.height; ++y)
    for (int x = 0; x < image.width; ++x) {
      const auto g = uint8_t(std::clamp(255.0f * (image.at(x, y) - lo) / (hi - lo), 0.0f, 255.0f));
      rgb.at<cv::Vec3b>(y, x) = {g, g, g};
    }
  const int r = std::max(3, int(std::round(fit.map ? 0.25 * fit.map->pitch_px() : 4.0)));
  for (const auto& p : fit.used_px) cv::circle(rgb, cv::Point(int(std::lround(p.x())), int(std::lround(p.y()))), r, {0, 255, 0}, 1);
  for (const auto& p : fit.rejected_px) cv::circle(rgb, cv::Point(int(std::lround(p.x())), int(std::lround(p.y()))), r, {255, 0, 0}, 1);
  write_png_u8(std::vector<uint8_t>(rgb.datastart, rgb.dataend), image.width, image.height, 3, path);
}

void run_fit(const FitOptions& o) {
  StageTimer timer;
  const DewarpModel model = parse_dewarp_model(o.model);
  check_output_path(o.out);
  if (!o.overlay.empty()) check_output_path(o.overlay);
  const GridModel grid = read_grid_model(o.grid);
  const Image image = read_image(o.image);
  timer.lap("read");
  DewarpFitOptions options;
  options.model = model;
  const DewarpFit fit = fit_dewarp(image, grid, options);
  timer.lap("fit");

  nlohmann::json doc = dewarp_fit_document(fit, grid, image.width, image.height);
  doc["inputs"] = {{"image", file_digest(o.image)}, {"grid", file_digest(o.grid)}};
  doc["provenance"] = provenance("dewarp fit", {{"model", o.model}}, doc["inputs"]);
  if (!o.overlay.empty()) write_overlay(image, fit, o.overlay);
  timer.lap("write");
  doc["timings_s"] = timer.json();
  write_json(doc, o.out);
  if (!fit.ok) throw MethodFailed(o.out + ": dewarp fit failed: " + fit.reason);
  std::printf("wrote %s (%s map, %d holes found, %d used, pitch %.3f px, residual mean %.4f max %.4f px)\n", o.out.c_str(),
              o.model.c_str(), fit.holes_found, fit.holes_used, fit.map->pitch_px(), fit.residual_mean_px, fit.residual_max_px);
}

void run_apply(const ApplyOptions& o) {
  if (o.in.empty() == o.points.empty()) throw_input_error("dewarp apply", "give exactly one of --in IMAGE and --points PTS.json");
  const DewarpMap map = DewarpMap::read(o.map);
  if (!o.points.empty()) {
    const PointList2 in = read_points_2d(o.points);
    PointList2 out;
    int inside = 0;
    for (const auto& p : in) {
      out.push_back(p ? map.correct_point(*p) : std::nullopt);
      inside += out.back().has_value();
    }
    write_points_2d(out, o.out);
    std::printf("wrote %s (%d of %zu points inside the map's field of view)\n", o.out.c_str(), inside, in.size());
    return;
  }
  if (!std::filesystem::is_regular_file(o.in)) throw_input_error(o.in, "no such file");
  const std::string name = lower_file_name(o.in);
  const bool stored_type = ends_with(name, ".png") || ends_with(name, ".tif") || ends_with(name, ".tiff") ||
                           ends_with(name, ".jpg") || ends_with(name, ".jpeg") || ends_with(name, ".bmp");
  if (!stored_type) {
    // DICOM, PFM, NIfTI, MetaImage, NRRD: the engine's reader, as float.
    const Image f = read_image(o.in);
    if (f.width != map.width() || f.height != map.height())
      throw_input_error(o.in, "is " + std::to_string(f.width) + "x" + std::to_string(f.height) + ", the map is for " +
                                  std::to_string(map.width()) + "x" + std::to_string(map.height()));
    if (!is_float_image_path(o.out)) throw_input_error(o.out, "a float image needs a float output (.tif, .pfm, .nii)");
    write_float_image(map.correct_image(f), o.out);
  } else {
    const cv::Mat image = read_stored_image(o.in);
    if (image.cols != map.width() || image.rows != map.height())
      throw_input_error(o.in, "is " + std::to_string(image.cols) + "x" + std::to_string(image.rows) + ", the map is for " +
                                  std::to_string(map.width()) + "x" + std::to_string(map.height()));
    if ((image.depth() == CV_32F || image.depth() == CV_64F) && !cv::checkRange(image))
      throw_input_error(o.in, "holds NaN or infinite pixels");
    write_stored_image(map.correct_image(image), o.out);
  }
  std::printf("wrote %s (%dx%d, corrected)\n", o.out.c_str(), map.width(), map.height());
}

}  // namespace

void add_dewarp_command(CLI::App& app) {
  auto* cmd = app.add_subcommand("dewarp", "Distortion correction: fit a map to a grid X-ray, apply it to images or points");
  cmd->require_subcommand(1);

  auto f = std::make_shared<FitOptions>();
  auto* fit = cmd->add_subcommand("fit", "Fit a distortion map (MAP.json) to an X-ray of the hole plate");
  fit->add_option("--image", f->image, "X-ray of the grid plate (log domain, holes bright)")->required();
  fit->add_option("--grid", f->grid, "GRID.json, the plate's model")->required();
  fit->add_option("--out", f->out, "MAP.json to write")->required();
  fit->add_option("--overlay", f->overlay, "PNG of the image with the used (green) and left-out (red) holes");
  fit->add_option("--model", f->model, "polynomial (global least squares, default) | bilinear (the seed's cells)")->capture_default_str();
  fit->callback([f] { run_fit(*f); });

  auto a = std::make_shared<ApplyOptions>();
  auto* apply = cmd->add_subcommand("apply", "Correct an image (--in) or a point list (--points) with a map");
  apply->add_option("--map", a->map, "MAP.json from dewarp fit")->required();
  auto* in = apply->add_option("--in", a->in, "Image to correct (same size as the map; written with the same type)");
  auto* pts = apply->add_option("--points", a->points, "Point list of distorted pixels");
  in->excludes(pts);
  apply->add_option("--out", a->out, "Corrected image or point list")->required();
  apply->callback([a] { run_apply(*a); });
}

}  // namespace fluoro::cli
