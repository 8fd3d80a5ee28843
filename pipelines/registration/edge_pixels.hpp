#pragma once
// Edge pixels of an X-ray for gradient projection registration: Canny edges (OpenCV) with the
// direction the expected (DRR) gradient should have there.
#include "engine/image.hpp"
#include "engine/ops.hpp"

namespace fluoro {

enum class XrayPolarity {
  log_domain,   // intensity = a - b * line integral, b > 0: bone dark (the default)
  bone_bright,  // display-inverted, b < 0
};

struct EdgeDetectionParams {
  // Canny hysteresis thresholds as fractions of the largest Sobel magnitude of the smoothed image.
  double low_fraction = 0.05, high_fraction = 0.15;
  double blur_sigma_px = 1.0;  // Gaussian pre-smoothing
  int max_pixels = 0;          // > 0: keep an evenly spread subset of at most this many
};

// A fixed pseudo-random subset (uniform over the edges) of at most max_pixels (all of them when max_pixels <= 0).
EdgePixels evenly_spread(const EdgePixels& e, int max_pixels);

// Throws InputError naming `what` when the image is empty or has no edges.
EdgePixels detect_edge_pixels(const Image& xray, XrayPolarity polarity, const EdgeDetectionParams& params,
                              const std::string& what);

}  // namespace fluoro
