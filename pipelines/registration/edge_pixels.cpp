#include "pipelines/registration/edge_pixels.hpp"

#include <algorithm>
#include <iterator>
#include <numeric>
#include <random>
#include <cmath>
#include <opencv2/imgproc.hpp>

#include "engine/error.hpp"
#include "engine/image_mat.hpp"
#include "engine/ray_setup.hpp"

namespace fluoro {

EdgePixels evenly_spread(const EdgePixels& e, int max_pixels) {
  if (max_pixels <= 0 || int(e.pixels.size()) <= max_pixels) return e;
  // A fixed pseudo-random sample (kept in raster order): a regular stride through raster order
  // would pick whole rows of some edges and none of others.
  std::vector<size_t> all(e.pixels.size()), keep;
  std::iota(all.begin(), all.end(), size_t(0));
  std::sample(all.begin(), all.end(), std::back_inserter(keep), size_t(max_pixels), std::mt19937_64(0x5eed));
  EdgePixels subset;
  for (size_t k : keep) {
    subset.pixels.push_back(e.pixels[k]);
    subset.directions.push_back(e.directions[k]);
  }
  return subset;
}

EdgePixels tile_ordered(const EdgePixels& e) {
  EdgePixels sorted;
  for (const uint32_t k : tile_order(e.pixels)) {
    sorted.pixels.push_back(e.pixels[k]);
    sorted.directions.push_back(e.directions[k]);
  }
  return sorted;
}

double noise_ratio(const cv::Mat& img) {
  // Noise: the median absolute fine-scale residual (image minus its 1-pixel Gaussian blur; on a
  // smooth X-ray only edges leave one, and they are few), against the edge contrast: the 99th
  // percentile of the blurred image's gradient magnitude.
  cv::Mat smooth, residual, gx, gy, mag;
  cv::GaussianBlur(img, smooth, cv::Size(0, 0), 1.0);
  cv::absdiff(img, smooth, residual);
  cv::Sobel(smooth, gx, CV_32F, 1, 0, 3, 0.125);
  cv::Sobel(smooth, gy, CV_32F, 0, 1, 3, 0.125);
  cv::magnitude(gx, gy, mag);
  const auto quantile = [](const cv::Mat& m, double q) {
    std::vector<float> v(m.begin<float>(), m.end<float>());
    const auto k = v.begin() + std::ptrdiff_t(q * double(v.size() - 1));
    std::nth_element(v.begin(), k, v.end());
    return double(*k);
  };
  const double contrast = quantile(mag, 0.99);
  return contrast > 0 ? 1.4826 * quantile(residual, 0.5) / contrast : 0.0;
}

EdgePixels detect_edge_pixels(const Image& xray, XrayPolarity polarity, const EdgeDetectionParams& params,
                              const std::string& what) {
  if (xray.empty()) throw_input_error(what, "empty image");
  return detect_edge_pixels(xray, polarity, params, what, noise_ratio(mat_view(xray)));
}

EdgePixels detect_edge_pixels(const Image& xray, XrayPolarity polarity, const EdgeDetectionParams& params,
                              const std::string& what, double ratio) {
  if (xray.empty()) throw_input_error(what, "empty image");
  cv::Mat img = mat_view(xray);
  cv::Mat smooth;
  // Noisy X-rays are smoothed more: by 1 + 1.5 x the noise ratio (at most 3x).
  const double blur = params.blur_sigma_px * (ratio > params.noisy_ratio ? std::min(3.0, 1.0 + 1.5 * ratio) : 1.0);
  if (blur > 0) cv::GaussianBlur(img, smooth, cv::Size(0, 0), blur);
  else smooth = img.clone();
  // Canny on float data: the Sobel derivatives go in as 16-bit integers, scaled so the largest
  // magnitude uses most of the range (Canny's thresholds are then fractions of it).
  cv::Mat gx, gy;
  cv::Sobel(smooth, gx, CV_32F, 1, 0, 3);
  cv::Sobel(smooth, gy, CV_32F, 0, 1, 3);
  cv::Mat mag;
  cv::magnitude(gx, gy, mag);
  double max_mag = 0;
  cv::minMaxLoc(mag, nullptr, &max_mag);
  if (!(max_mag > 0)) throw_input_error(what, "no edge pixels (the image is flat)");
  const double scale = 16000.0 / max_mag;
  cv::Mat dx, dy, edges;
  gx.convertTo(dx, CV_16S, scale);
  gy.convertTo(dy, CV_16S, scale);
  cv::Canny(dx, dy, edges, params.low_fraction * 16000.0, params.high_fraction * 16000.0, true);

  EdgePixels e;
  // The DRR gradient grows with attenuation; a log-domain X-ray darkens with it, so the expected
  // direction is minus the image gradient (plus for bone-bright images).
  const float sign = polarity == XrayPolarity::log_domain ? -1.0f : 1.0f;
  for (int y = 0; y < edges.rows; ++y)
    for (int x = 0; x < edges.cols; ++x) {
      if (!edges.at<uint8_t>(y, x)) continue;
      const Eigen::Vector2f g(gx.at<float>(y, x), gy.at<float>(y, x));
      const float n = g.norm();
      if (!(n > 0)) continue;
      e.pixels.emplace_back(float(x), float(y));
      e.directions.push_back(sign * g / n);
    }
  if (e.pixels.empty()) throw_input_error(what, "no edge pixels found");
  return evenly_spread(e, params.max_pixels);
}

}  // namespace fluoro
