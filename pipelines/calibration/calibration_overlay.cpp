#include "pipelines/calibration/calibration_overlay.hpp"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

#include "engine/display_image.hpp"

namespace fluoro {

std::vector<uint8_t> calibration_overlay(const Image& image, const std::vector<DarkCircle>& circles,
                                         const CameraCalibration& result) {
  cv::Mat rgb = display_rgb(image);
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
