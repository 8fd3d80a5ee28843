#pragma once
// The nearest of a set of 2D points (the contour pixels of an X-ray, or the projected apparent
// contour of the bone mesh) to query positions in an image, exactly, through a uniform grid of
// buckets searched ring by ring. Building is O(points), so the map is cheap enough to rebuild at
// every ICP iteration (a distance transform of the whole image cost 40 % of a sweep's time); a
// query costs a few buckets near a point and more the farther it is from every point.
//
// Where queries repeat in the same places (an ICP's 30-40 iterations ask the map of an X-ray's
// contour pixels for the nearest to nearly the same projected mesh points), the map can also
// remember, per cell of 4 x 4 pixels, the points that can be nearest to any position in it (the
// candidates): the first query in a cell finds them, later ones compare only those. The answer is
// the same either way; a map asked once per cell (rebuilt each iteration) is better off without.
#include <Eigen/Core>
#include <atomic>
#include <memory>
#include <vector>

namespace fluoro {

class NearestPointMap {
 public:
  // Points outside the image [-0.5, width - 0.5) x [-0.5, height - 0.5), or not finite, are ignored.
  // remember_candidates: keep each cell's candidates once found (for maps queried many times).
  NearestPointMap(const std::vector<Eigen::Vector2f>& points, int width, int height, bool remember_candidates = false);
  bool empty() const { return kept_ == 0; }
  // Index of the nearest point to (x, y) (ties: the lowest index), or -1 when (x, y) lies outside
  // the image or the map is empty. Safe to call from several threads at once; never throws.
  int nearest(double x, double y) const;

 private:
  // The bucket column (n = columns_) or row (n = rows_) of image coordinate v, clamped to the grid.
  int bucket_index(double v, int n) const;
  // The ring search over the buckets from (x, y) (clamped to the grid).
  int search_rings(double x, double y) const;
  // Cell c's candidates: a new array, its count first then the indices ascending; &too_many_
  // when there are more than kMaxCandidates, or no memory for the array (there the ring search
  // answers).
  int* find_candidates(int c) const;
  // The squared distance every path compares, in one place so that they round alike.
  double squared_distance(int i, double x, double y) const {
    const double dx = points_[size_t(i)].x() - x, dy = points_[size_t(i)].y() - y;
    return dx * dx + dy * dy;
  }

  int width_, height_;
  double cell_;                     // bucket side in pixels
  int columns_ = 0, rows_ = 0;
  std::vector<int> first_;          // per bucket, its range in `members_` (CSR layout)
  std::vector<int> members_;        // point indices, bucket by bucket, ascending within a bucket
  std::vector<Eigen::Vector2f> points_;
  size_t kept_ = 0;

  // The candidate cells: squares of `side_` pixels (4, more on images of over 2^16 such cells),
  // smaller than the buckets where points are dense. Each cell's list is published once, by
  // whichever thread first finds it (lock-free: a thread that loses the race drops its own, equal
  // list). No cells when the map does not remember candidates.
  static constexpr int kMaxCandidates = 64;
  struct CandidateLists {
    std::unique_ptr<std::atomic<int*>[]> lists;  // per cell; null: not found yet
    size_t cells = 0;
    CandidateLists() = default;
    explicit CandidateLists(size_t n);
    CandidateLists(CandidateLists&& o) noexcept;
    CandidateLists& operator=(CandidateLists&& o) noexcept;
    ~CandidateLists();
  };
  int side_ = 4, cell_columns_ = 0, cell_rows_ = 0;
  CandidateLists candidates_;
  static int too_many_;  // the list of a cell with more than kMaxCandidates candidates
};

}  // namespace fluoro
