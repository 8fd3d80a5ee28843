#include "pipelines/registration/livewire.hpp"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <opencv2/imgproc/segmentation.hpp>
#include <stdexcept>

#include "engine/image_mat.hpp"

namespace fluoro {

std::vector<Eigen::Vector2f> livewire_path(const Image& xray, const std::vector<Eigen::Vector2f>& clicks) {
  if (clicks.empty()) return {};
  // The tool takes 8-bit images: the X-ray, smoothed by a pixel (detector noise would otherwise
  // make every pixel an edge), stretched between its 0.5th and 99.5th percentiles.
  cv::Mat image = mat_view(xray), smooth;
  cv::GaussianBlur(image, smooth, cv::Size(0, 0), 1.0);
  std::vector<float> sorted(smooth.begin<float>(), smooth.end<float>());
  const auto quantile = [&](double q) {
    auto it = sorted.begin() + std::ptrdiff_t(q * double(sorted.size() - 1));
    std::nth_element(sorted.begin(), it, sorted.end());
    return double(*it);
  };
  const double lo = quantile(0.005), hi = quantile(0.995);
  cv::Mat grey;
  smooth.convertTo(grey, CV_8U, hi > lo ? 255.0 / (hi - lo) : 1.0, hi > lo ? -lo * 255.0 / (hi - lo) : 0.0);

  cv::segmentation::IntelligentScissorsMB tool;
  tool.applyImage(grey);
  const auto pixel = [&](const Eigen::Vector2f& p) {
    return cv::Point(std::clamp(int(std::lround(p.x())), 0, xray.width - 1),
                     std::clamp(int(std::lround(p.y())), 0, xray.height - 1));
  };
  std::vector<Eigen::Vector2f> path{Eigen::Vector2f(float(pixel(clicks[0]).x), float(pixel(clicks[0]).y))};
  for (size_t i = 0; i + 1 < clicks.size(); ++i) {
    const cv::Point from = pixel(clicks[i]), to = pixel(clicks[i + 1]);
    if (from == to) continue;
    tool.buildMap(from);
    std::vector<cv::Point> segment;
    tool.getContour(to, segment);
    // From `from` to `to`; `from` is already in the path.
    if (!segment.empty() && segment.front() == to && segment.back() == from) std::reverse(segment.begin(), segment.end());
    for (const cv::Point& q : segment)
      if (q != from) path.emplace_back(float(q.x), float(q.y));
    if (segment.empty() || segment.back() != to) path.emplace_back(float(to.x), float(to.y));
  }
  return path;
}

}  // namespace fluoro
