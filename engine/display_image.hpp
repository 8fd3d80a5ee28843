#pragma once
// An X-ray as an 8-bit RGB image to draw an overlay on.
#include <opencv2/core.hpp>

#include "engine/image.hpp"

namespace fluoro {

// Grey levels from the 0.5th to the 99.5th percentile mapped to 0-255 (CV_8UC3, RGB order): a noisy
// X-ray's few photon-starved pixels would otherwise take the whole range and leave the rest pale.
cv::Mat display_rgb(const Image& image);

}  // namespace fluoro
