#include "pipelines/panorama/field_of_view.hpp"

#include <algorithm>
#include <opencv2/imgproc.hpp>
#include <vector>

namespace fluoro {

cv::Mat field_of_view_mask(const cv::Mat& image, int erode_px) {
  double lo = 0, hi = 0;
  cv::minMaxLoc(image, &lo, &hi);
  cv::Mat mask;
  // The surround is the darkest value and flat; anything exposed is above it by far more than the
  // noise (even behind metal the detector keeps a floor above black).
  cv::threshold(image, mask, lo + 0.01 * (hi - lo), 255, cv::THRESH_BINARY);
  mask.convertTo(mask, CV_8U);
  // Keep the largest region and fill its holes: dark metal inside the field stays inside.
  std::vector<std::vector<cv::Point>> contours;
  cv::findContours(mask, contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_SIMPLE);
  cv::Mat filled = cv::Mat::zeros(image.size(), CV_8U);
  if (!contours.empty()) {
    const auto largest = std::max_element(contours.begin(), contours.end(), [](const auto& a, const auto& b) {
      return cv::contourArea(a) < cv::contourArea(b);
    });
    cv::drawContours(filled, std::vector<std::vector<cv::Point>>{*largest}, 0, cv::Scalar(255), cv::FILLED);
  }
  if (erode_px > 0)
    cv::erode(filled, filled, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * erode_px + 1, 2 * erode_px + 1)),
              cv::Point(-1, -1), 1, cv::BORDER_CONSTANT, cv::Scalar(0));
  return filled;
}

}  // namespace fluoro
