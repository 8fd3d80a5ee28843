// fluoro calibrate: a camera from one X-ray of a fiducial phantom (shared/docs/FORMATS.md, "Camera
// calibration"): detect the balls, pair them with PHANTOM.json, DLT + RQ + Levenberg-Marquardt,
// and CAMERA.json, a camera file whose world frame is the phantom's.
#include <cstdio>
#include <optional>
#include <string>

#include "apps/fluoro/commands.hpp"
#include "apps/fluoro/result_files.hpp"
#include "engine/error.hpp"
#include "engine/image_io.hpp"
#include "engine/json_io.hpp"
#include "engine/phantom_model.hpp"
#include "pipelines/calibration/calibration_overlay.hpp"
#include "pipelines/calibration/camera_calibration.hpp"
#include "pipelines/calibration/dark_circle_detector.hpp"
#include "pipelines/calibration/dewarp_map.hpp"

namespace fluoro::cli {
namespace {

struct CalibrateOptions {
  std::string image, phantom, dewarp, out, overlay;
};

nlohmann::json pixel_json(const Eigen::Vector2d& p) { return {p.x(), p.y()}; }

void run(const CalibrateOptions& o) {
  StageTimer timer;
  const PhantomModel phantom = read_phantom_model(o.phantom);
  const Image image = read_image(o.image);
  std::optional<DewarpMap> map;
  if (!o.dewarp.empty()) {
    map = DewarpMap::read(o.dewarp);
    if (map->width() != image.width || map->height() != image.height)
      throw_input_error(o.dewarp, "the map corrects " + std::to_string(map->width()) + "x" +
                                      std::to_string(map->height()) + " images, " + o.image + " is " +
                                      std::to_string(image.width) + "x" + std::to_string(image.height));
  }
  timer.lap("read");

  // The balls are found in the image as acquired (a resampled image would blur their edges);
  // with a dewarp their centres are then moved into the corrected image, whose camera this is.
  // A centre outside the map's field of view is dropped: the map does not vouch for it.
  std::vector<DarkCircle> circles = detect_dark_circles(image);
  const size_t found = circles.size();
  if (map) {
    std::vector<DarkCircle> inside;
    for (DarkCircle c : circles)
      if (const auto p = map->correct_point(c.centre_px)) {
        c.centre_px = *p;
        inside.push_back(c);
      }
    circles = std::move(inside);
  }
  std::vector<DetectedCentre> centres;
  for (const auto& c : circles) centres.push_back({c.centre_px, c.crowded});
  const int width = map ? map->width() : image.width, height = map ? map->height() : image.height;
  timer.lap("detect");

  const CameraCalibration cal = calibrate_camera(phantom, centres, width, height);
  timer.lap("calibrate");

  nlohmann::json doc = nlohmann::json::object();
  if (cal.ok) doc = camera_to_json(cal.camera);
  doc["status"] = cal.ok ? "ok" : "failed";
  if (!cal.ok) doc["reason"] = cal.failure_reason;
  doc["fiducials_found"] = found;
  if (map) doc["fiducials_outside_dewarp_field"] = found - circles.size();
  nlohmann::json matched = nlohmann::json::array(), back = nlohmann::json::array();
  for (const auto& f : cal.fiducials) {
    const std::string& id = phantom.fiducials[size_t(f.fiducial)].id;
    nlohmann::json m = {{"id", id}, {"pixel", pixel_json(f.pixel)}};
    if (cal.ok) {
      m["residual_px"] = f.residual_px;
      m["outlier"] = f.outlier;
      back.push_back({{"id", id}, {"distance_mm", f.backprojection_mm}});
    }
    matched.push_back(m);
  }
  doc["fiducials_matched"] = matched;
  if (cal.ok) {
    doc["reprojection_px"] = {{"rms", cal.rms_px}, {"max", cal.max_px}};
    doc["backprojection_mm"] = back;
  }
  doc["inputs"] = {{"image", file_digest(o.image)}, {"phantom", file_digest(o.phantom)}};
  if (map) doc["inputs"]["dewarp"] = file_digest(o.dewarp);
  if (!o.overlay.empty()) {
    // With a dewarp, the overlay is drawn on the corrected image, where the centres now are.
    write_png_u8(calibration_overlay(map ? map->correct_image(image) : image, circles, cal), width, height, 3,
                 o.overlay);
    timer.lap("overlay");
  }
  doc["timings_s"] = timer.json();
  doc["timings_s"]["total"] = timer.total();
  write_json(doc, o.out);
  if (!cal.ok) throw MethodFailed(o.out + ": calibration failed: " + cal.failure_reason);
  std::printf("%s: %zu balls found, %zu matched, reprojection rms %.4f px (max %.4f), f = %.1f px, %.3f s\n",
              o.out.c_str(), found, cal.fiducials.size(), cal.rms_px, cal.max_px, cal.camera.K(0, 0),
              timer.total());
}

}  // namespace

void add_calibrate_command(CLI::App& app) {
  auto o = std::make_shared<CalibrateOptions>();
  auto* cmd = app.add_subcommand("calibrate", "Calibrate a camera from one X-ray of a fiducial phantom");
  cmd->add_option("--image", o->image, "Phantom X-ray (log domain: balls dark)")->required();
  cmd->add_option("--phantom", o->phantom, "PHANTOM.json: the fiducials in the phantom's frame")->required();
  cmd->add_option("--dewarp", o->dewarp,
                  "MAP.json of fluoro dewarp fit: the camera then describes the corrected image");
  cmd->add_option("--out", o->out, "CAMERA.json: the camera (world = phantom frame) and the fit's report")->required();
  cmd->add_option("--overlay", o->overlay, "PNG: detections (yellow) and reprojected fiducials (green)");
  cmd->callback([o] { run(*o); });
}

}  // namespace fluoro::cli
