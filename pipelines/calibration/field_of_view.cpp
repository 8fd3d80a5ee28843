#include "pipelines/calibration/field_of_view.hpp"

#include <algorithm>
#include <opencv2/imgproc.hpp>

namespace fluoro {

double percentile(std::vector<float> v, double q) {
  if (v.empty()) return 0;
  const size_t k = std::min(v.size() - 1, size_t(q * double(v.size() - 1)));
  std::nth_element(v.begin(), v.begin() + std::ptrdiff_t(k), v.end());
  return v[k];
}

cv::Mat field_of_view_mask(const Image& image) {
  if (image.empty()) return {};
  const cv::Mat f(image.height, image.width, CV_32F, const_cast<float*>(image.pixels.data()));
  cv::Mat smooth;
  cv::medianBlur(f, smooth, 5);
  const std::vector<float> all(smooth.begin<float>(), smooth.end<float>());
  const double lo = *std::min_element(all.begin(), all.end()), hi = percentile(all, 0.99);
  if (!(hi > lo)) return cv::Mat::zeros(f.size(), CV_8U);
  return smooth > lo + 0.05 * (hi - lo);
}

}  // namespace fluoro
