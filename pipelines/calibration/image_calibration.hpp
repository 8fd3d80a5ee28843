#pragma once
// Camera calibration from one phantom X-ray, as `fluoro calibrate` runs it: the balls found in the
// image as acquired, moved into the corrected image when there is a dewarp map, paired and
// calibrated there; and the CAMERA.json document of the outcome (shared/docs/FORMATS.md).
#include <nlohmann/json.hpp>
#include <vector>

#include "engine/image.hpp"
#include "engine/phantom_model.hpp"
#include "pipelines/calibration/camera_calibration.hpp"
#include "pipelines/calibration/dark_circle_detector.hpp"
#include "pipelines/calibration/dewarp_map.hpp"

namespace fluoro {

// The detections and the calibration of one image.
struct ImageCalibration {
  size_t balls_found = 0;          // dark circles in the whole image
  std::vector<DarkCircle> circles; // those the calibration saw, in the camera's pixels (corrected with a map)
  int width = 0, height = 0;       // the camera's image: the corrected one with a map
  bool dewarped = false;
  CameraCalibration calibration;
  double detect_seconds = 0, calibrate_seconds = 0;  // wall clock of the two steps
};

// Balls are detected in the image as acquired (a resampled image would blur their edges); with a
// map, each centre is then moved into the corrected image and one outside the map's field of view
// is dropped (the map does not vouch for it). The map must be for the image's size (the caller checks).
ImageCalibration calibrate_image(const Image& image, const PhantomModel& phantom, const DewarpMap* map = nullptr);

// CAMERA.json without `inputs` and timings: the camera file's keys when the calibration succeeded
// (never a guessed camera otherwise), `status` (and `reason`), `fiducials_found`,
// `fiducials_matched` (id, pixel), `reprojection_px`, `backprojection_mm`.
nlohmann::json calibration_document(const ImageCalibration& result, const PhantomModel& phantom);

}  // namespace fluoro
