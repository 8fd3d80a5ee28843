#include "pipelines/registration/nearest_point_map.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <new>
#include <utility>

namespace fluoro {
namespace {

bool inside(double x, double y, int width, int height) {
  return std::isfinite(x) && std::isfinite(y) && x >= -0.5 && y >= -0.5 && x < width - 0.5 && y < height - 0.5;
}

}  // namespace

NearestPointMap::NearestPointMap(const std::vector<Eigen::Vector2f>& points, int width, int height,
                                 bool remember_candidates)
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
  const auto bucket = [&](const Eigen::Vector2f& p) { return bucket_index(p.y(), rows_) * columns_ + bucket_index(p.x(), columns_); };
  first_.assign(size_t(columns_) * size_t(rows_) + 1, 0);
  for (const int i : kept) ++first_[size_t(bucket(points[size_t(i)])) + 1];
  for (size_t b = 1; b < first_.size(); ++b) first_[b] += first_[b - 1];
  members_.resize(kept_);
  std::vector<int> fill(first_.begin(), first_.end() - 1);
  for (const int i : kept) members_[size_t(fill[size_t(bucket(points[size_t(i)]))]++)] = i;

  // Candidate cells of 4 x 4 pixels, larger on images of more than 2^16 such cells (8 bytes a
  // cell, and a list for each cell asked for).
  if (!remember_candidates || kept_ == 0 || width <= 0 || height <= 0) return;
  side_ = std::max(4, int(std::ceil(std::sqrt(double(width) * double(height) / 65536.0))));
  cell_columns_ = (width + side_ - 1) / side_;
  cell_rows_ = (height + side_ - 1) / side_;
  candidates_ = CandidateLists(size_t(cell_columns_) * size_t(cell_rows_));
}

int NearestPointMap::too_many_ = -1;

NearestPointMap::CandidateLists::CandidateLists(size_t n) : lists(new std::atomic<int*>[n]()), cells(n) {}

NearestPointMap::CandidateLists::CandidateLists(CandidateLists&& o) noexcept
    : lists(std::move(o.lists)), cells(std::exchange(o.cells, 0)) {}

NearestPointMap::CandidateLists& NearestPointMap::CandidateLists::operator=(CandidateLists&& o) noexcept {
  if (this != &o) {
    CandidateLists old(std::move(*this));
    lists = std::move(o.lists);
    cells = std::exchange(o.cells, 0);
  }
  return *this;
}

NearestPointMap::CandidateLists::~CandidateLists() {
  for (size_t c = 0; c < cells; ++c) {
    int* l = lists[c].load(std::memory_order_relaxed);
    if (l != &too_many_) delete[] l;
  }
}

int NearestPointMap::bucket_index(double v, int n) const { return std::clamp(int((v + 0.5) / cell_), 0, n - 1); }

int NearestPointMap::search_rings(double x, double y) const {
  const int cx = bucket_index(x, columns_), cy = bucket_index(y, rows_);
  double best = std::numeric_limits<double>::infinity();
  int best_index = -1;
  const auto visit = [&](int bx, int by) {
    if (bx < 0 || by < 0 || bx >= columns_ || by >= rows_) return;
    const size_t b = size_t(by) * size_t(columns_) + size_t(bx);
    for (int m = first_[b]; m < first_[b + 1]; ++m) {
      const int i = members_[size_t(m)];
      const double d2 = squared_distance(i, x, y);
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

int* NearestPointMap::find_candidates(int c) const {
  // The cell's square, in image coordinates (pixel centres at integers).
  const int sx = c % cell_columns_, sy = c / cell_columns_;
  const double x0 = sx * side_ - 0.5, x1 = x0 + side_, y0 = sy * side_ - 0.5, y1 = y0 + side_;
  // Any point q bounds the nearest distance from every position in the square by q's distance to
  // the square's farthest corner, R; so the nearest lies within R of the square. q: the point
  // nearest the square's centre, which makes R small.
  const int q = search_rings(0.5 * (x0 + x1), 0.5 * (y0 + y1));
  if (q < 0) return &too_many_;
  const double qx = points_[size_t(q)].x(), qy = points_[size_t(q)].y();
  const double fx = std::max(qx - x0, x1 - qx), fy = std::max(qy - y0, y1 - qy);
  // A margin far above the rounding of the squared distances the queries compare.
  const double r = std::sqrt(fx * fx + fy * fy) * (1 + 1e-9) + 1e-6;
  const int bx0 = bucket_index(x0 - r, columns_), bx1 = bucket_index(x1 + r, columns_);
  const int by0 = bucket_index(y0 - r, rows_), by1 = bucket_index(y1 + r, rows_);
  int found[kMaxCandidates];
  int count = 0;
  for (int by = by0; by <= by1; ++by)
    for (int bx = bx0; bx <= bx1; ++bx) {
      const size_t b = size_t(by) * size_t(columns_) + size_t(bx);
      for (int m = first_[b]; m < first_[b + 1]; ++m) {
        const int i = members_[size_t(m)];
        const double px = points_[size_t(i)].x(), py = points_[size_t(i)].y();
        const double dx = std::max({0.0, x0 - px, px - x1}), dy = std::max({0.0, y0 - py, py - y1});
        if (dx * dx + dy * dy > r * r) continue;
        if (count == kMaxCandidates) return &too_many_;
        found[count++] = i;
      }
    }
  std::sort(found, found + count);
  int* list = new (std::nothrow) int[size_t(count) + 1];
  if (!list) return &too_many_;
  list[0] = count;
  std::copy(found, found + count, list + 1);
  return list;
}

int NearestPointMap::nearest(double x, double y) const {
  if (empty() || !inside(x, y, width_, height_)) return -1;
  if (candidates_.cells == 0) return search_rings(x, y);
  const int sx = std::min(int((x + 0.5) / side_), cell_columns_ - 1);
  const int sy = std::min(int((y + 0.5) / side_), cell_rows_ - 1);
  const int c = sy * cell_columns_ + sx;
  std::atomic<int*>& slot = candidates_.lists[size_t(c)];
  int* list = slot.load(std::memory_order_acquire);
  if (!list) {
    int* mine = find_candidates(c);
    if (slot.compare_exchange_strong(list, mine, std::memory_order_acq_rel, std::memory_order_acquire)) {
      list = mine;
    } else if (mine != &too_many_) {
      delete[] mine;  // another thread's list, the same, is `list` now
    }
  }
  if (list == &too_many_) return search_rings(x, y);
  double best = std::numeric_limits<double>::infinity();
  int best_index = -1;
  for (int k = 1; k <= list[0]; ++k) {  // ascending indices: the first of equal distances wins
    const int i = list[k];
    const double d2 = squared_distance(i, x, y);
    if (d2 < best) {
      best = d2;
      best_index = i;
    }
  }
  return best_index;
}

}  // namespace fluoro
