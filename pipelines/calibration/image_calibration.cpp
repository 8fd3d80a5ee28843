#include "pipelines/calibration/image_calibration.hpp"

#include <chrono>

#include "engine/json_io.hpp"

namespace fluoro {

ImageCalibration calibrate_image(const Image& image, const PhantomModel& phantom, const DewarpMap* map) {
  using clock = std::chrono::steady_clock;
  const auto t0 = clock::now();
  ImageCalibration r;
  r.circles = detect_dark_circles(image);
  r.balls_found = r.circles.size();
  r.width = map ? map->width() : image.width;
  r.height = map ? map->height() : image.height;
  r.dewarped = map != nullptr;
  if (map) {
    std::vector<DarkCircle> inside;
    for (DarkCircle c : r.circles)
      if (const auto p = map->correct_point(c.centre_px)) {
        c.centre_px = *p;
        inside.push_back(c);
      }
    r.circles = std::move(inside);
  }
  std::vector<DetectedCentre> centres;
  for (const auto& c : r.circles) centres.push_back({c.centre_px, c.crowded});
  const auto t1 = clock::now();
  r.calibration = calibrate_camera(phantom, centres, r.width, r.height);
  r.detect_seconds = std::chrono::duration<double>(t1 - t0).count();
  r.calibrate_seconds = std::chrono::duration<double>(clock::now() - t1).count();
  return r;
}

nlohmann::json calibration_document(const ImageCalibration& r, const PhantomModel& phantom) {
  const CameraCalibration& cal = r.calibration;
  nlohmann::json doc = cal.ok ? camera_to_json(cal.camera) : nlohmann::json::object();
  doc["status"] = cal.ok ? "ok" : "failed";
  if (!cal.ok) doc["reason"] = cal.failure_reason;
  doc["fiducials_found"] = r.balls_found;
  if (r.dewarped) doc["fiducials_outside_dewarp_field"] = r.balls_found - r.circles.size();
  nlohmann::json matched = nlohmann::json::array(), back = nlohmann::json::array();
  for (const auto& f : cal.fiducials) {
    const std::string& id = phantom.fiducials[size_t(f.fiducial)].id;
    nlohmann::json m = {{"id", id}, {"pixel", {f.pixel.x(), f.pixel.y()}}};
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
  return doc;
}

}  // namespace fluoro
