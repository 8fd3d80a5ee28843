// fluoro panorama: one panoramic image of a long bone from overlapping fluoroscopic frames, aligned
// on an orthopaedic ruler's graduations (shared/docs/FORMATS.md "Panorama", docs/panorama.md).
#include <algorithm>
#include <cmath>
#include <functional>
#include <optional>
#include <cstdio>
#include <exception>
#include <tbb/parallel_for.h>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "apps/fluoro/commands.hpp"
#include "apps/fluoro/global_options.hpp"
#include "apps/fluoro/provenance.hpp"
#include "apps/fluoro/result_files.hpp"
#include "engine/error.hpp"
#include "engine/image_io.hpp"
#include "engine/image_mat.hpp"
#include "engine/json_io.hpp"
#include "pipelines/calibration/dewarp_map.hpp"
#include "pipelines/panorama/panorama.hpp"
#include "pipelines/panorama/panorama_document.hpp"
#include "pipelines/panorama/panorama_overlay.hpp"

namespace fluoro::cli {
namespace {

struct PanoramaCliOptions {
  std::vector<std::string> images;
  std::string contours, dewarp, blend = "max", out, report, overlay;
  double graduation_mm = 5;
  bool allow_partial = false;
};

cv::Mat to_mat(const Image& image) {
  return mat_view(image).clone();
}

void run(const PanoramaCliOptions& o) {
  StageTimer timer;
  // Both outputs checked before either is written: a bad --report must not leave a PNG behind.
  check_output_path(o.out);
  check_output_path(o.report);
  if (!o.overlay.empty()) check_output_path(o.overlay);
  if (o.images.size() < 2) throw_input_error("--images", "a panorama needs at least 2 frames");
  if (!(o.graduation_mm > 0) || !std::isfinite(o.graduation_mm))
    throw_input_error("--graduation-mm", "must be a positive number of millimetres");
  // The distortion correction (seed Table I step 1): every frame goes through the map before the
  // ruler is looked for, so the pipeline sees the corrected frames only.
  std::optional<DewarpMap> map;
  if (!o.dewarp.empty()) map = DewarpMap::read(o.dewarp);
  // The frames decoded in parallel; the first unreadable one (in the order given) is the error.
  const size_t n = o.images.size();
  std::vector<Image> images(n);
  std::vector<std::exception_ptr> errors(n);
  tbb::parallel_for(size_t(0), n, [&](size_t i) {
    try {
      images[i] = read_image(o.images[i]);
    } catch (...) {
      errors[i] = std::current_exception();
    }
  });
  for (size_t i = 0; i < n; ++i) {
    if (errors[i]) std::rethrow_exception(errors[i]);
    const Image& image = images[i];
    if (image.width != images[0].width || image.height != images[0].height)
      throw_input_error(o.images[i], "its size " + std::to_string(image.width) + " x " + std::to_string(image.height) +
                                         " differs from the first frame's " + std::to_string(images[0].width) + " x " +
                                         std::to_string(images[0].height));
    if (map && (image.width != map->width() || image.height != map->height()))
      throw_input_error(o.dewarp, "the map is for " + std::to_string(map->width()) + " x " + std::to_string(map->height()) +
                                      " images, the frames are " + std::to_string(image.width) + " x " +
                                      std::to_string(image.height));
  }
  std::vector<cv::Mat> frames(n);
  tbb::parallel_for(size_t(0), n, [&](size_t i) { frames[i] = to_mat(map ? map->correct_image(images[i]) : images[i]); });
  images.clear();
  // C.json's points are traced on the frames as acquired (FORMATS.md): the map takes them to the
  // corrected frames the alignment works on.
  const auto identity = [](const Eigen::Vector2d& p) { return std::optional<Eigen::Vector2d>(p); };
  const auto correct = [&](const Eigen::Vector2d& p) { return map->correct_point(p); };
  std::optional<PlaneContours> contours;
  if (!o.contours.empty()) {
    if (map)
      contours = plane_contours_from_json(read_json(o.contours), o.contours, int(frames.size()), frames[0].cols, frames[0].rows, correct);
    else
      contours = plane_contours_from_json(read_json(o.contours), o.contours, int(frames.size()), frames[0].cols, frames[0].rows, identity);
  }
  timer.lap("read");

  PanoramaOptions options;
  options.graduation_mm = o.graduation_mm;
  options.blend = parse_panorama_blend(o.blend, "--blend");
  const Panorama p = align_panorama(frames, options, contours);
  timer.lap("align");

  nlohmann::json doc = panorama_document(p, o.images, o.graduation_mm, o.blend, o.dewarp, contours.has_value(), o.allow_partial);
  const bool failed = doc["status"] == "failed";
  const std::string reason = doc.value("reason", std::string());
  const bool frames_missing = doc["partial"].get<bool>();
  nlohmann::json inputs = nlohmann::json::array();
  for (const auto& path : o.images) inputs.push_back(file_digest(path));
  if (!o.contours.empty()) inputs.push_back(file_digest(o.contours));
  if (!o.dewarp.empty()) inputs.push_back(file_digest(o.dewarp));
  doc["inputs"] = inputs;
  doc["provenance"] = provenance("panorama",
                                 {{"graduation_mm", o.graduation_mm},
                                  {"blend", o.blend},
                                  {"dewarp", !o.dewarp.empty()},
                                  {"plane", contours ? "contours" : "ruler"},
                                  {"allow_partial", o.allow_partial},
                                  {"frames", o.images.size()}},
                                 inputs);
  if (!failed) {
    const cv::Mat pano = compose_panorama(frames, p, options.blend);
    timer.lap("compose");
    std::vector<uint16_t> pixels(size_t(pano.rows) * size_t(pano.cols));
    tbb::parallel_for(0, pano.rows, [&](int y) {  // rows in parallel: 4.7 M pixels on the bench set
      const float* row = pano.ptr<float>(y);
      for (int x = 0; x < pano.cols; ++x)
        pixels[size_t(y) * size_t(pano.cols) + size_t(x)] = uint16_t(std::clamp(std::lround(row[x]), 0L, 65535L));
    });
    write_png_u16(pixels, pano.cols, pano.rows, o.out);
    timer.lap("write");
    if (!o.overlay.empty()) {
      const cv::Mat rgb = panorama_overlay(pano, frames, p);
      std::vector<uint8_t> bytes(rgb.total() * 3);
      for (int y = 0; y < rgb.rows; ++y)
        for (int x = 0; x < rgb.cols; ++x) {
          const cv::Vec3b c = rgb.at<cv::Vec3b>(y, x);  // BGR -> RGB
          for (int k = 0; k < 3; ++k) bytes[(size_t(y) * size_t(rgb.cols) + size_t(x)) * 3 + size_t(k)] = c[2 - k];
        }
      write_png_u8(bytes, rgb.cols, rgb.rows, 3, o.overlay);
      timer.lap("overlay");
    }
  }
  doc["timings_s"] = timer.json();
  doc["timings_s"]["total"] = timer.total();
  write_json(doc, o.report);
  if (failed) throw MethodFailed(reason.empty() ? "the frames could not be composed" : reason);
  std::printf("wrote %s (%d x %d, %.5f mm/pixel in the %s plane, %s) and %s\n", o.out.c_str(), p.width, p.height,
              p.mm_per_pixel, p.plane.c_str(), frames_missing ? "some frames left out" : "all frames aligned",
              o.report.c_str());
}

}  // namespace

void add_panorama_command(CLI::App& app) {
  auto o = std::make_shared<PanoramaCliOptions>();
  auto* cmd = app.add_subcommand("panorama", "Compose a long-bone panorama from overlapping frames aligned on a ruler");
  cmd->add_option("--images", o->images, "Frames in acquisition order along the bone (log domain, metal dark)")
      ->required()
      ->expected(1, -1);
  cmd->add_option("--graduation-mm", o->graduation_mm, "Ruler graduation spacing, mm")->capture_default_str();
  cmd->add_option("--dewarp", o->dewarp,
                  "MAP.json (fluoro dewarp fit): every frame is corrected with it, C.json's points too");
  cmd->add_option("--plane-contours", o->contours,
                  "C.json: one contour traced on two consecutive frames; the panorama is then metric in its plane");
  cmd->add_option("--blend", o->blend, "Overlapping pixels: max | mean | median | min")
      ->check(CLI::IsMember({"max", "mean", "median", "min"}))
      ->capture_default_str();
  cmd->add_option("--out", o->out, "Panorama, 16-bit PNG (the inputs' intensities)")->required();
  cmd->add_option("--report", o->report, "PANO.json (FORMATS.md)")->required();
  cmd->add_option("--overlay", o->overlay,
                  "PNG of the panorama with the ruler threads (red), graduations found (green) and seams (cyan)");
  cmd->add_flag("--allow-partial", o->allow_partial, "Compose the frames aligned to the first even if others are not");
  cmd->callback([o] { run(*o); });
}

}  // namespace fluoro::cli
