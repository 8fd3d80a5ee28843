#include "engine/display_image.hpp"

#include <algorithm>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "engine/image_mat.hpp"

namespace fluoro {

cv::Mat display_rgb(const Image& image) {
  const cv::Mat src = mat_view(image);
  std::vector<float> sorted(image.pixels);
  const size_t lo_i = sorted.size() / 200, hi_i = sorted.size() - 1 - sorted.size() / 200;
  std::nth_element(sorted.begin(), sorted.begin() + long(lo_i), sorted.end());
  const float lo = sorted[lo_i];
  std::nth_element(sorted.begin(), sorted.begin() + long(hi_i), sorted.end());
  const float hi = std::max(sorted[hi_i], lo + 1e-6f);
  cv::Mat grey, rgb;
  src.convertTo(grey, CV_8U, 255.0 / (hi - lo), -255.0 * lo / (hi - lo));
  cv::cvtColor(grey, rgb, cv::COLOR_GRAY2RGB);
  return rgb;
}

}  // namespace fluoro
