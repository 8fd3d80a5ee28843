#pragma once
// An X-ray and its camera reduced by an integer factor, so that neither side exceeds a size: the
// gradient correlation judges poses on about 256 pixels a side, the global search on about 128.
// Whole f x f blocks are averaged (the last partial row or column of blocks is dropped), and the
// camera's intrinsics are scaled to match, so a DRR rendered with the reduced camera lines up with
// the reduced image pixel for pixel.
#include <opencv2/core.hpp>

#include "engine/camera.hpp"
#include "engine/image.hpp"

namespace fluoro {

struct ReducedView {
  PinholeCamera camera;
  cv::Mat image;  // CV_32F, camera.height x camera.width
  int factor = 1;
};

// The smallest integer factor that brings the larger side to at most max_side pixels.
ReducedView reduce_view(const PinholeCamera& camera, const Image& image, int max_side);

}  // namespace fluoro
