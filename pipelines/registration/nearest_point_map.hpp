#pragma once
// The nearest of a set of 2D points (the contour pixels of an X-ray, or the projected apparent
// contour of the bone mesh) to query positions in an image, exactly, through a uniform grid of
// buckets searched ring by ring. Building is O(points), so the map is cheap enough to rebuild at
// every ICP iteration (a distance transform of the whole image cost 40 % of a sweep's time); a
// query costs a few buckets near a point and more the farther it is from every point.
#include <Eigen/Core>
#include <vector>

namespace fluoro {

class NearestPointMap {
 public:
  // Points outside the image [-0.5, width - 0.5) x [-0.5, height - 0.5), or not finite, are ignored.
  NearestPointMap(const std::vector<Eigen::Vector2f>& points, int width, int height);
  bool empty() const { return kept_ == 0; }
  // Index of the nearest point to (x, y) (ties: the lowest index), or -1 when (x, y) lies outside
  // the image or the map is empty.
  int nearest(double x, double y) const;

 private:
  int width_, height_;
  double cell_;                     // bucket side in pixels
  int columns_ = 0, rows_ = 0;
  std::vector<int> first_;          // per bucket, its range in `members_` (CSR layout)
  std::vector<int> members_;        // point indices, bucket by bucket, ascending within a bucket
  std::vector<Eigen::Vector2f> points_;
  size_t kept_ = 0;
};

}  // namespace fluoro
