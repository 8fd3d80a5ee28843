#pragma once
// A picture to check a calibration by eye: the X-ray in grey, every detected ball circled in
// yellow, each paired fiducial's reprojection as a green cross (red when left out as an outlier).
#include <cstdint>
#include <vector>

#include "engine/image.hpp"
#include "pipelines/calibration/camera_calibration.hpp"
#include "pipelines/calibration/dark_circle_detector.hpp"

namespace fluoro {

// RGB pixels (interleaved, width x height x 3) of the overlay; `result` may be a failed one.
std::vector<uint8_t> calibration_overlay(const Image& image, const std::vector<DarkCircle>& circles,
                                         const CameraCalibration& result);

}  // namespace fluoro
