// fluoro calibrate: a camera from one X-ray of a fiducial phantom (shared/docs/FORMATS.md, "Camera
// calibration"): detect the balls, pair them with PHANTOM.json, DLT + RQ + Levenberg-Marquardt,
// and CAMERA.json, a camera file whose world frame is the phantom's.
#include <cstdio>
#include <optional>
#include <string>

#include "apps/fluoro/commands.hpp"
#include "apps/fluoro/global_options.hpp"
#include "apps/fluoro/provenance.hpp"
#include "apps/fluoro/result_files.hpp"
#include "engine/error.hpp"
#include "engine/image_io.hpp"
#include "engine/json_io.hpp"
#include "engine/phantom_model.hpp"
#include "pipelines/calibration/calibration_overlay.hpp"
#include "pipelines/calibration/image_calibration.hpp"

namespace fluoro::cli {
namespace {

struct CalibrateOptions {
  std::string image, phantom, dewarp, out, overlay;
};

void run(const CalibrateOptions& o) {
  StageTimer timer;
  check_output_path(o.out);
  if (!o.overlay.empty()) check_output_path(o.overlay);
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

  const ImageCalibration result = calibrate_image(image, phantom, map ? &*map : nullptr);
  const CameraCalibration& cal = result.calibration;
  timer.lap("calibrate");  // split into its two steps below

  nlohmann::json doc = calibration_document(result, phantom);
  doc["inputs"] = {{"image", file_digest(o.image)}, {"phantom", file_digest(o.phantom)}};
  if (map) doc["inputs"]["dewarp"] = file_digest(o.dewarp);
  doc["provenance"] = provenance("calibrate", {{"dewarp", map.has_value()}, {"overlay", !o.overlay.empty()}}, doc["inputs"]);
  if (!o.overlay.empty()) {
    // With a dewarp, the overlay is drawn on the corrected image, where the centres now are.
    write_png_u8(calibration_overlay(map ? map->correct_image(image) : image, result.circles, cal), result.width,
                 result.height, 3, o.overlay);
    timer.lap("overlay");
  }
  doc["timings_s"] = timer.json();
  doc["timings_s"]["detect"] = result.detect_seconds;
  doc["timings_s"]["calibrate"] = result.calibrate_seconds;
  doc["timings_s"]["total"] = timer.total();
  write_json(doc, o.out);
  if (!cal.ok) throw MethodFailed(o.out + ": calibration failed: " + cal.failure_reason);
  std::printf("%s: %zu balls found, %zu matched, reprojection rms %.4f px (max %.4f), f = %.1f px, %.3f s\n",
              o.out.c_str(), result.balls_found, cal.fiducials.size(), cal.rms_px, cal.max_px, cal.camera.K(0, 0),
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
