#include "pipelines/registration/nearest_point_map.hpp"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

namespace fluoro {

NearestPointMap::NearestPointMap(const std::vector<Eigen::Vector2f>& points, int width, int height)
    : width_(width), height_(height) {
  cv::Mat free(height, width, CV_8U, cv::Scalar(255));
  std::vector<int> owner;
  std::vector<cv::Point> seeds;
  for (size_t i = 0; i < points.size(); ++i) {
    if (!std::isfinite(points[i].x()) || !std::isfinite(points[i].y())) continue;
    const int x = int(std::lround(points[i].x())), y = int(std::lround(points[i].y()));
    if (x < 0 || y < 0 || x >= width || y >= height || free.at<uint8_t>(y, x) == 0) continue;
    free.at<uint8_t>(y, x) = 0;
    seeds.emplace_back(x, y);
    owner.push_back(int(i));
  }
  if (seeds.empty()) return;
  cv::Mat distance;
  cv::distanceTransform(free, distance, labels_, cv::DIST_L2, cv::DIST_MASK_5, cv::DIST_LABEL_PIXEL);
  // Each seed pixel carries its own label: map labels back to point indices.
  int max_label = 0;
  for (const auto& s : seeds) max_label = std::max(max_label, labels_.at<int>(s));
  owner_of_label_.assign(size_t(max_label) + 1, -1);
  for (size_t i = 0; i < seeds.size(); ++i) owner_of_label_[size_t(labels_.at<int>(seeds[i]))] = owner[i];
}

int NearestPointMap::nearest(double x, double y) const {
  if (empty() || !std::isfinite(x) || !std::isfinite(y)) return -1;
  const long xi = std::lround(x), yi = std::lround(y);
  if (xi < 0 || yi < 0 || xi >= width_ || yi >= height_) return -1;
  const int label = labels_.at<int>(int(yi), int(xi));
  return label >= 0 && size_t(label) < owner_of_label_.size() ? owner_of_label_[size_t(label)] : -1;
}

}  // namespace fluoro
