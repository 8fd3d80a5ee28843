#pragma once
// Edge pixels of an X-ray for gradient projection registration: Canny edges (OpenCV) with the
// direction the expected (DRR) gradient should have there.
#include <opencv2/core.hpp>

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
  // Noisy X-rays (fine-scale noise above noisy_ratio of the edge contrast, see noise_ratio: a
  // clean DRR measures 0.01 to 0.03, 0.3 % Gaussian noise about 0.4) are smoothed more before
  // Canny, by 1 + 1.5 x the ratio, at most 3 times.
  double noisy_ratio = 0.1;
};

// Fine-scale noise of an image (CV_32F) relative to its edge contrast: about 0 for a clean DRR.
double noise_ratio(const cv::Mat& image);

// A fixed pseudo-random subset (uniform over the edges) of at most max_pixels (all of them when max_pixels <= 0).
EdgePixels evenly_spread(const EdgePixels& e, int max_pixels);

// The same pixels in the backends' tile order (engine/ray_setup.hpp), so that scoring them
// thousands of times does not sort them every time.
EdgePixels tile_ordered(const EdgePixels& e);

// Throws InputError naming `what` when the image is empty or has no edges.
EdgePixels detect_edge_pixels(const Image& xray, XrayPolarity polarity, const EdgeDetectionParams& params,
                              const std::string& what);
// The same with the image's noise_ratio already measured (one X-ray, several detections).
EdgePixels detect_edge_pixels(const Image& xray, XrayPolarity polarity, const EdgeDetectionParams& params,
                              const std::string& what, double measured_noise_ratio);

}  // namespace fluoro
