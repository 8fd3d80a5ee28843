#pragma once
// The nearest of a set of 2D points to any pixel of an image, from one exact distance transform
// (OpenCV's, labelling every pixel with its closest point): O(1) per query after O(pixels).
#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <vector>

namespace fluoro {

class NearestPointMap {
 public:
  // Points outside the image are ignored; of points sharing a pixel, the first is kept.
  NearestPointMap(const std::vector<Eigen::Vector2f>& points, int width, int height);
  bool empty() const { return owner_of_label_.empty(); }
  // Index of the nearest point to pixel (x, y) (rounded), or -1 outside the image or when empty.
  int nearest(double x, double y) const;

 private:
  int width_, height_;
  cv::Mat labels_;
  std::vector<int> owner_of_label_;
};

}  // namespace fluoro
