#include "pipelines/registration/nearest_point_map.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace fluoro {
namespace {

bool inside(double x, double y, int width, int height) {
  return std::isfinite(x) && std::isfinite(y) && x >= -0.5 && y >= -0.5 && x < width - 0.5 && y < height - 0.5;
}

}  // namespace

NearestPointMap::NearestPointMap(const std::vector<Eigen::Vector2f>& points, int width, int height)
    : width_(width), height_(height), points_(points) {
  std::vector<int> kept;
  for (size_t i = 0; i < points.size(); ++i)
    if (inside(points[i].x(), points[i].y(), width, height)) kept.push_back(int(i));
  kept_ = kept.size();
  // About two points per bucket along a contour: buckets of side ~ sqrt(area / points) * 2 hold
  // a handful of points each and keep the rings to search short.
  cell_ = std::clamp(2.0 * std::sqrt(double(width) * height / double(std::max<size_t>(kept_, 1))), 4.0, 64.0);
  columns_ = std::max(1, int(std::ceil(width / cell_)));
  rows_ = std::max(1, int(std::ceil(height / cell_)));
  const auto bucket = [&](const Eigen::Vector2f& p) {
    const int cx = std::clamp(int((p.x() + 0.5) / cell_), 0, columns_ - 1);
    const int cy = std::clamp(int((p.y() + 0.5) / cell_), 0, rows_ - 1);
    return cy * columns_ + cx;
  };
  first_.assign(size_t(columns_) * size_t(rows_) + 1, 0);
  for (const int i : kept) ++first_[size_t(bucket(points[size_t(i)])) + 1];
  for (size_t b = 1; b < first_.size(); ++b) first_[b] += first_[b - 1];
  members_.resize(kept_);
  std::vector<int> fill(first_.begin(), first_.end() - 1);
  for (const int i : kept) members_[size_t(fill[size_t(bucket(points[size_t(i)]))]++)] = i;
}

int NearestPointMap::nearest(double x, double y) const {
  if (empty() || !inside(x, y, width_, height_)) return -1;
  const int cx = std::clamp(int((x + 0.5) / cell_), 0, columns_ - 1);
  const int cy = std::clamp(int((y + 0.5) / cell_), 0, rows_ - 1);
  double best = std::numeric_limits<double>::infinity();
  int best_index = -1;
  const auto visit = [&](int bx, int by) {
    if (bx < 0 || by < 0 || bx >= columns_ || by >= rows_) return;
    const size_t b = size_t(by) * size_t(columns_) + size_t(bx);
    for (int m = first_[b]; m < first_[b + 1]; ++m) {
      const int i = members_[size_t(m)];
      const double dx = points_[size_t(i)].x() - x, dy = points_[size_t(i)].y() - y;
      const double d2 = dx * dx + dy * dy;
      if (d2 < best || (d2 == best && i < best_index)) {
        best = d2;
        best_index = i;
      }
    }
  };
  const int max_ring = std::max(columns_, rows_);
  for (int r = 0; r <= max_ring; ++r) {
    // Every point in ring r is at least (r - 1) buckets away along one axis.
    if (best_index >= 0 && r >= 1) {
      const double gap = (r - 1) * cell_;
      if (gap * gap > best) break;
    }
    if (r == 0) {
      visit(cx, cy);
      continue;
    }
    for (int bx = cx - r; bx <= cx + r; ++bx) {
      visit(bx, cy - r);
      visit(bx, cy + r);
    }
    for (int by = cy - r + 1; by <= cy + r - 1; ++by) {
      visit(cx - r, by);
      visit(cx + r, by);
    }
  }
  return best_index;
}

}  // namespace fluoro
