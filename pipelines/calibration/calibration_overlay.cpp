#include "pipelines/calibration/calibration_overlay.hpp"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

namespace fluoro {

std::vector<uint8_t> calibration_overlay(const Image& image, const std::vector<DarkCircle>& circles,
                                         const CameraCalibration& result) {
  cv::Mat src(image.height, image.width, CV_32F, const_cast<float*>(image.pixels.data()));
  // Grey levels from the 0.5th to the 99.5th percentile: a noisy X-ray's few photon-starved
  // pixels would otherwise take the whole range and leave the balls pale.
  std::vector<float> sorted(image.pixels);
  const size_t lo_i = sorted.size() / 200, hi_i = sorted.size() - 1 - sorted.size() / 200;
  std::nth_element(sorted.begin(), sorted.begin() + long(lo_i), sorted.end());
  const float lo = sorted[lo_i];
  std::nth_element(sorted.begin(), sorted.begin() + long(hi_i), sorted.end());
  const float hi = std::max(sorted[hi_i], lo + 1e-6f);
  cv::Mat grey, rgb;
  src.convertTo(grey, CV_8U, 255.0 / (hi - lo), -255.0 * lo / (hi - lo));
  cv::cvtColor(grey, rgb, cv::COLOR_GRAY2RGB);
  const int scale = 16;  // sub-pixel drawing: 4 fractional bits
  auto pt = [&](const Eigen::Vector2d& p) { return cv::Point(int(std::lround(p.x() * scale)), int(std::lround(p.y() * scale))); };
  for (const auto& c : circles)
    cv::circle(rgb, pt(c.centre_px), int(std::lround((c.radius_px + 2) * scale)), cv::Scalar(255, 220, 0), 1,
               cv::LINE_AA, 4);
  for (const auto& f : result.fiducials) {
    if (!f.reprojected.allFinite()) continue;
    const cv::Scalar colour = f.outlier ? cv::Scalar(255, 40, 40) : cv::Scalar(0, 255, 0);
    cv::drawMarker(rgb, cv::Point(int(std::lround(f.reprojected.x())), int(std::lround(f.reprojected.y()))), colour,
                   cv::MARKER_CROSS, 9, 1);
  }
  return std::vector<uint8_t>(rgb.data, rgb.data + rgb.total() * 3);
}

}  // namespace fluoro
