#include "pipelines/panorama/panorama_overlay.hpp"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

#include "engine/field_of_view.hpp"

namespace fluoro {
namespace {

cv::Point to_panorama(const Eigen::Matrix3d& H, const Eigen::Vector2d& px) {
  const Eigen::Vector3d q = H * Eigen::Vector3d(px.x(), px.y(), 1);
  return {int(std::lround(q.x())), int(std::lround(q.y()))};
}

}  // namespace

cv::Mat panorama_overlay(const cv::Mat& panorama_image, const std::vector<cv::Mat>& frames, const Panorama& p) {
  // Grey: the covered pixels' 1st-99th percentile stretched to 0-255 (the surround stays black).
  std::vector<float> covered;
  for (int y = 0; y < panorama_image.rows; y += 2)
    for (int x = 0; x < panorama_image.cols; x += 2)
      if (const float v = panorama_image.at<float>(y, x); v > 0) covered.push_back(v);
  const double lo = percentile(covered, 0.01), hi = std::max(lo + 1, percentile(covered, 0.99));
  cv::Mat grey;
  panorama_image.convertTo(grey, CV_8U, 255.0 / (hi - lo), -lo * 255.0 / (hi - lo));
  cv::Mat out;
  cv::cvtColor(grey, out, cv::COLOR_GRAY2BGR);
  const int thick = std::max(1, panorama_image.cols / 1500);
  // Seams: every aligned frame's field of view, outlined where it lands in the panorama.
  for (size_t i = 0; i < frames.size() && i < p.frames.size(); ++i) {
    if (!p.frames[i].aligned) continue;
    const Eigen::Matrix3d& H = p.frames[i].H_panorama_frame;
    cv::Mat frame32;
    frames[i].convertTo(frame32, CV_32F);
    std::vector<std::vector<cv::Point>> outlines;
    cv::findContours(field_of_view_mask(frame32, 2), outlines, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_SIMPLE);
    for (auto& outline : outlines)
      for (auto& q : outline) q = to_panorama(H, Eigen::Vector2d(q.x, q.y));
    cv::polylines(out, outlines, true, cv::Scalar(255, 255, 0), thick, cv::LINE_AA);
  }
  // The rulers: thread (red) and graduations (green ticks across it, on the marks' side).
  for (const PanoramaFrame& f : p.frames) {
    if (!f.aligned || f.thread_px.size() != 2) continue;
    const Eigen::Matrix3d& H = f.H_panorama_frame;
    cv::line(out, to_panorama(H, f.thread_px[0]), to_panorama(H, f.thread_px[1]), cv::Scalar(0, 0, 255), thick, cv::LINE_AA);
    const Eigen::Vector2d across = f.thread_normal * f.thread_width_px;
    for (const Eigen::Vector2d& g : f.graduations_px)
      cv::line(out, to_panorama(H, g + 0.5 * across), to_panorama(H, g + 2.5 * across), cv::Scalar(0, 255, 0), thick,
               cv::LINE_AA);
  }
  return out;
}

}  // namespace fluoro
