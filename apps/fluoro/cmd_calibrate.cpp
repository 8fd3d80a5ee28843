// fluoro calibrate: a camera from one X-ray of a fiducial phantom (shared/docs/FORMATS.md, "Camera
// calibration"): detect the balls, pair them with PHANTOM.json, DLT + RQ + Levenberg-Marquardt,
// and CAMERA.json, a camera file whose world frame is the phantom's.
#include <cstdio>
#include <string>

#include "apps/fluoro/commands.hpp"
#include "apps/fluoro/result_files.hpp"
#include "engine/image_io.hpp"
#include "engine/json_io.hpp"
#include "engine/phantom_model.hpp"
#include "pipelines/calibration/calibration_overlay.hpp"
#include "pipelines/calibration/camera_calibration.hpp"
#include "pipelines/calibration/dark_circle_detector.hpp"

namespace fluoro::cli {
namespace {

struct CalibrateOptions {
  std::string image, phantom, out, overlay;
};

nlohmann::json pixel_json(const Eigen::Vector2d& p) { return {p.x(), p.y()}; }

void run(const CalibrateOptions& o) {
  StageTimer timer;
  const PhantomModel phantom = read_phantom_model(o.phantom);
  const Image image = read_image(o.image);
  timer.lap("read");

  const std::vector<DarkCircle> circles = detect_dark_circles(image);
  // The calibration takes centres in the camera's pixel frame: a dewarp's point correction
  // (dropping the centres it cannot map) goes here, and the size becomes the corrected image's.
  std::vector<DetectedCentre> centres;
  for (const auto& c : circles) centres.push_back({c.centre_px, c.crowded});
  const int width = image.width, height = image.height;
  timer.lap("detect");

  const CameraCalibration cal = calibrate_camera(phantom, centres, width, height);
  timer.lap("calibrate");

  nlohmann::json doc = nlohmann::json::object();
  if (cal.ok) doc = camera_to_json(cal.camera);
  doc["status"] = cal.ok ? "ok" : "failed";
  if (!cal.ok) doc["reason"] = cal.failure_reason;
  doc["fiducials_found"] = circles.size();
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
  if (!o.overlay.empty()) {
    write_png_u8(calibration_overlay(image, circles, cal), width, height, 3, o.overlay);
    timer.lap("overlay");
  }
  doc["timings_s"] = timer.json();
  doc["timings_s"]["total"] = timer.total();
  write_json(doc, o.out);
  if (!cal.ok) throw MethodFailed(o.out + ": calibration failed: " + cal.failure_reason);
  std::printf("%s: %zu balls found, %zu matched, reprojection rms %.4f px (max %.4f), f = %.1f px, %.3f s\n",
              o.out.c_str(), circles.size(), cal.fiducials.size(), cal.rms_px, cal.max_px, cal.camera.K(0, 0),
              timer.total());
}

}  // namespace

void add_calibrate_command(CLI::App& app) {
  auto o = std::make_shared<CalibrateOptions>();
  auto* cmd = app.add_subcommand("calibrate", "Calibrate a camera from one X-ray of a fiducial phantom");
  cmd->add_option("--image", o->image, "Phantom X-ray (log domain: balls dark)")->required();
  cmd->add_option("--phantom", o->phantom, "PHANTOM.json: the fiducials in the phantom's frame")->required();
  cmd->add_option("--out", o->out, "CAMERA.json: the camera (world = phantom frame) and the fit's report")->required();
  cmd->add_option("--overlay", o->overlay, "PNG: detections (yellow) and reprojected fiducials (green)");
  cmd->callback([o] { run(*o); });
}

}  // namespace fluoro::cli
