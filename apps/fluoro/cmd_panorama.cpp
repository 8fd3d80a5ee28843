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
#include "engine/json_io.hpp"
#include "pipelines/calibration/dewarp_map.hpp"
#include "pipelines/panorama/panorama.hpp"
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
  return cv::Mat(image.height, image.width, CV_32F, const_cast<float*>(image.pixels.data())).clone();
}

// C.json: {"frames": [i, i+1], "polylines": [[[u, v], ...], [[u, v], ...]]} in the original frames'
// pixels. `correct` maps such a pixel to the corrected frame (identity without a dewarp; the dewarp's
// correct_point plugs in here) and returns nullopt outside its field of view.
PlaneContours read_plane_contours(const std::string& path, int frames, int width, int height,
                                  const std::function<std::optional<Eigen::Vector2d>(const Eigen::Vector2d&)>& correct) {
  const nlohmann::json j = read_json(path);
  if (!j.is_object() || !j.contains("frames") || !j["frames"].is_array() || j["frames"].size() != 2 ||
      !j["frames"][0].is_number_integer() || !j["frames"][1].is_number_integer())
    throw_input_error(path, "\"frames\" must be two frame indices [i, i+1]");
  const int a = j["frames"][0].get<int>(), b = j["frames"][1].get<int>();
  if (a < 0 || b >= frames || b != a + 1)
    throw_input_error(path, "\"frames\" [" + std::to_string(a) + ", " + std::to_string(b) +
                                "] must be two consecutive frames among the " + std::to_string(frames) + " given");
  if (!j.contains("polylines") || !j["polylines"].is_array() || j["polylines"].size() != 2)
    throw_input_error(path, "\"polylines\" must hold two polylines, one per frame");
  PlaneContours c;
  c.first = a;
  for (int k = 0; k < 2; ++k) {
    const auto& line = j["polylines"][size_t(k)];
    if (!line.is_array() || line.size() < 2) throw_input_error(path, "each polyline needs at least 2 points");
    for (const auto& p : line) {
      if (!p.is_array() || p.size() != 2 || !p[0].is_number() || !p[1].is_number())
        throw_input_error(path, "a polyline point must be [u, v]");
      const Eigen::Vector2d q(p[0].get<double>(), p[1].get<double>());
      if (!q.allFinite() || q.x() < -0.5 || q.y() < -0.5 || q.x() > width - 0.5 || q.y() > height - 0.5)
        throw_input_error(path, "point (" + std::to_string(q.x()) + ", " + std::to_string(q.y()) + ") of frame " +
                                    std::to_string(a + k) + " is outside the " + std::to_string(width) + " x " +
                                    std::to_string(height) + " image");
      const auto corrected = correct(q);
      if (!corrected) throw_input_error(path, "a polyline point is outside the dewarp's field of view");
      c.polylines[k].push_back(*corrected);
    }
  }
  return c;
}

PanoramaBlend parse_blend(const std::string& s) {
  if (s == "max") return PanoramaBlend::Max;
  if (s == "mean") return PanoramaBlend::Mean;
  if (s == "median") return PanoramaBlend::Median;
  return PanoramaBlend::Min;
}

nlohmann::json matrix_json(const Eigen::Matrix3d& m) {
  nlohmann::json rows = nlohmann::json::array();
  for (int r = 0; r < 3; ++r) rows.push_back({m(r, 0), m(r, 1), m(r, 2)});
  return rows;
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
      contours = read_plane_contours(o.contours, int(frames.size()), frames[0].cols, frames[0].rows, correct);
    else
      contours = read_plane_contours(o.contours, int(frames.size()), frames[0].cols, frames[0].rows, identity);
  }
  timer.lap("read");

  PanoramaOptions options;
  options.graduation_mm = o.graduation_mm;
  options.blend = parse_blend(o.blend);
  const Panorama p = align_panorama(frames, options, contours);
  timer.lap("align");

  // The first frame that could not be aligned names the failure (FORMATS.md: never placed by guess).
  std::string reason;
  bool frames_missing = false;
  for (size_t i = 0; i < p.frames.size(); ++i)
    if (!p.frames[i].aligned) {
      frames_missing = true;
      if (reason.empty())
        reason = "frame " + std::to_string(i) + " (" + o.images[i] + ") cannot be aligned: " + p.frames[i].problem;
    }
  const bool reference_missing = !p.frames[0].aligned;
  // Contours given but their plane not found (their frames unaligned, or no crossing points).
  const bool contour_problem = contours.has_value() && p.plane != "contours";
  if (reason.empty()) reason = p.failure;
  const bool failed = reference_missing || p.width <= 0 || (frames_missing && !o.allow_partial) || contour_problem;
  nlohmann::json doc;
  doc["status"] = failed ? "failed" : "ok";
  if (failed) doc["reason"] = reason;
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
  doc["size"] = {p.width, p.height};
  doc["mm_per_pixel"] = p.mm_per_pixel;
  doc["plane"] = p.plane;
  doc["graduation_mm"] = o.graduation_mm;
  doc["blend"] = o.blend;
  doc["dewarp"] = o.dewarp.empty() ? nlohmann::json(nullptr) : nlohmann::json(o.dewarp);
  doc["partial"] = frames_missing;
  doc["ruler_mm_per_pixel"] = p.ruler_mm_per_pixel;
  doc["plane_scale"] = p.plane_scale;
  doc["uncertainty"] = {{"scale_relative", p.scale_relative_sigma},
                        {"position_px", std::max(p.position_sigma_px, p.alignment_rms_px)},
                        {"alignment_rms_px", p.alignment_rms_px}};
  nlohmann::json jf = nlohmann::json::array();
  for (size_t i = 0; i < p.frames.size(); ++i) {
    const PanoramaFrame& f = p.frames[i];
    nlohmann::json e;
    e["file"] = o.images[i];
    e["aligned"] = f.aligned;
    e["confidence"] = f.confidence;
    e["overlap"] = f.overlap ? nlohmann::json(*f.overlap) : nlohmann::json(nullptr);
    e["H_panorama_frame"] = f.aligned ? matrix_json(f.H_panorama_frame) : nlohmann::json(nullptr);
    e["rotation_deg"] = f.rotation_deg;
    e["graduations"] = f.graduations;
    if (!f.aligned) e["problem"] = f.problem;
    jf.push_back(e);
  }
  doc["frames"] = jf;
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
