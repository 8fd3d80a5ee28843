#include "engine/field_of_view.hpp"

#include <algorithm>
#include <utility>
#include <opencv2/imgproc.hpp>

#include "engine/ellipse_erosion.hpp"

namespace fluoro {

double percentile(std::vector<float> v, double q) {
  if (v.empty()) return 0;
  const size_t k = std::min(v.size() - 1, size_t(q * double(v.size() - 1)));
  std::nth_element(v.begin(), v.begin() + std::ptrdiff_t(k), v.end());
  return v[k];
}

cv::Mat field_of_view_mask(const cv::Mat& image, int erode_px) {
  if (image.empty()) return {};
  cv::Mat f, smooth;
  image.convertTo(f, CV_32F);
  cv::medianBlur(f, smooth, 5);
  // smooth is a fresh, continuous matrix: its values copied once and handed to the partial sort.
  std::vector<float> all(smooth.ptr<float>(), smooth.ptr<float>() + smooth.total());
  const double lo = *std::min_element(all.begin(), all.end()), hi = percentile(std::move(all), 0.99);
  if (!(hi > lo)) return cv::Mat::zeros(image.size(), CV_8U);
  const cv::Mat lit = smooth > lo + 0.05 * (hi - lo);
  // The largest region with its holes filled: an occluder inside the field is still inside it.
  std::vector<std::vector<cv::Point>> contours;
  cv::findContours(lit, contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_SIMPLE);
  cv::Mat filled = cv::Mat::zeros(image.size(), CV_8U);
  if (!contours.empty()) {
    const auto largest = std::max_element(contours.begin(), contours.end(), [](const auto& a, const auto& b) {
      return cv::contourArea(a) < cv::contourArea(b);
    });
    cv::drawContours(filled, std::vector<std::vector<cv::Point>>{*largest}, 0, cv::Scalar(255), cv::FILLED);
  }
  if (erode_px > 0)
    filled = erode_ellipse(filled, 2 * erode_px + 1);
  return filled;
}

}  // namespace fluoro
