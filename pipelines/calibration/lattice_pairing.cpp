// Growing the lattice. A frontier node k lattice steps from indexed holes is predicted from an affine
// fit of the indexed holes around it; the nearest free blob within 0.3 of the local pitch takes it.
// Adjacent nodes are tried first (k = 1); only when growth stops are larger gaps (an occluder's band)
// bridged, up to 15 pitches (by a local quadratic beyond two), and every success goes back to k = 1.
#include "pipelines/calibration/lattice_pairing.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <unordered_map>

#include "pipelines/calibration/polynomial_map.hpp"

namespace fluoro {
namespace {

using NodeMap = std::map<std::pair<int, int>, int>;  // (i, j) -> index into the holes list

// Buckets of blob centres on a square grid, for nearest-blob queries near a prediction.
class BlobIndex {
 public:
  BlobIndex(const std::vector<Eigen::Vector2d>& c, double cell) : c_(c), cell_(cell) {
    for (size_t k = 0; k < c.size(); ++k) buckets_[key(c[k])].push_back(int(k));
  }
  // Nearest blob within `radius` of p that `taken` does not mark; -1 if none.
  int nearest(const Eigen::Vector2d& p, double radius, const std::vector<bool>& taken) const {
    int best = -1;
    double best_d = radius;
    const long cx = long(std::floor(p.x() / cell_)), cy = long(std::floor(p.y() / cell_));
    const long reach = long(std::ceil(radius / cell_));
    for (long y = cy - reach; y <= cy + reach; ++y)
      for (long x = cx - reach; x <= cx + reach; ++x) {
        const auto it = buckets_.find(pack(x, y));
        if (it == buckets_.end()) continue;
        for (int k : it->second) {
          const double d = (c_[size_t(k)] - p).norm();
          if (d < best_d && !taken[size_t(k)]) best_d = d, best = k;
        }
      }
    return best;
  }
  // All blobs within radius of p (other than `self`).
  std::vector<int> within(const Eigen::Vector2d& p, double radius, int self) const {
    std::vector<int> out;
    const long cx = long(std::floor(p.x() / cell_)), cy = long(std::floor(p.y() / cell_));
    const long reach = long(std::ceil(radius / cell_));
    for (long y = cy - reach; y <= cy + reach; ++y)
      for (long x = cx - reach; x <= cx + reach; ++x) {
        const auto it = buckets_.find(pack(x, y));
        if (it == buckets_.end()) continue;
        for (int k : it->second)
          if (k != self && (c_[size_t(k)] - p).norm() < radius) out.push_back(k);
      }
    return out;
  }

 private:
  static long long pack(long x, long y) { return (long long)(x) * 1000003LL + y; }
  long long key(const Eigen::Vector2d& p) const { return pack(long(std::floor(p.x() / cell_)), long(std::floor(p.y() / cell_))); }
  const std::vector<Eigen::Vector2d>& c_;
  double cell_;
  std::unordered_map<long long, std::vector<int>> buckets_;
};

double median_nearest_distance(const std::vector<Eigen::Vector2d>& c) {
  std::vector<double> d;
  for (size_t a = 0; a < c.size(); ++a) {
    double best = 1e300;
    for (size_t b = 0; b < c.size(); ++b)
      if (a != b) best = std::min(best, (c[a] - c[b]).squaredNorm());
    d.push_back(std::sqrt(best));
  }
  std::nth_element(d.begin(), d.begin() + std::ptrdiff_t(d.size() / 2), d.end());
  return d[d.size() / 2];
}

bool fit_affine(const std::vector<std::pair<Eigen::Vector2d, Eigen::Vector2d>>& pairs, Eigen::Matrix2d& A,
                Eigen::Vector2d& t) {
  if (pairs.size() < 3) return false;
  Eigen::MatrixXd M(pairs.size(), 3);
  Eigen::MatrixXd Y(pairs.size(), 2);
  for (size_t k = 0; k < pairs.size(); ++k) {
    M.row(Eigen::Index(k)) << pairs[k].first.x(), pairs[k].first.y(), 1.0;
    Y.row(Eigen::Index(k)) = pairs[k].second.transpose();
  }
  const Eigen::Matrix3d normal = M.transpose() * M;
  if (std::abs(normal.determinant()) < 1e-9 * std::pow(normal.trace(), 3)) return false;  // collinear
  const Eigen::MatrixXd X = normal.ldlt().solve(M.transpose() * Y);  // 3 x 2
  A = X.topRows(2).transpose();
  t = X.row(2).transpose();
  return std::abs(A.determinant()) > 0;
}

// Prediction of node (i0, j0) from the indexed holes within `radius` lattice steps: affine for the
// next neighbours; quadratic when bridging a gap, where an affine's error grows with the square of
// the jump (a few pixels over ten pitches of image-intensifier pincushion).
bool predict_node(const std::vector<LatticeHole>& holes, const std::vector<Eigen::Vector2d>& c, int i0, int j0,
                  int radius, bool quadratic, Eigen::Vector2d& prediction, double& local_pitch) {
  std::vector<std::pair<Eigen::Vector2d, Eigen::Vector2d>> pairs;
  for (const auto& h : holes)
    if (std::abs(h.i - i0) <= radius && std::abs(h.j - j0) <= radius)
      pairs.push_back({Eigen::Vector2d(h.i - i0, h.j - j0), c[size_t(h.blob)]});
  Eigen::Matrix2d A;
  if (!fit_affine(pairs, A, prediction)) return false;
  local_pitch = std::sqrt(std::abs(A.determinant()));
  if (!quadratic || pairs.size() < 15) return true;
  Eigen::MatrixXd M(pairs.size(), 6);
  Eigen::MatrixXd Y(pairs.size(), 2);
  for (size_t k = 0; k < pairs.size(); ++k) {
    const double x = pairs[k].first.x(), y = pairs[k].first.y();
    M.row(Eigen::Index(k)) << 1, x, y, x * x, x * y, y * y;
    Y.row(Eigen::Index(k)) = pairs[k].second.transpose();
  }
  const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(M);
  if (qr.rank() < 6) return true;  // the holes lie on too few lines for a curvature: keep the affine
  prediction = qr.solve(Y).row(0).transpose();
  return true;
}

}  // namespace

bool local_lattice_affine(const std::vector<LatticeHole>& holes, const std::vector<Eigen::Vector2d>& centres, int i0,
                          int j0, int radius, Eigen::Matrix2d& A, Eigen::Vector2d& t) {
  std::vector<std::pair<Eigen::Vector2d, Eigen::Vector2d>> pairs;
  for (const auto& h : holes)
    if (std::abs(h.i - i0) <= radius && std::abs(h.j - j0) <= radius)
      pairs.push_back({Eigen::Vector2d(h.i, h.j), centres[size_t(h.blob)]});
  return fit_affine(pairs, A, t);
}

std::vector<LatticeHole> pair_lattice(const std::vector<Eigen::Vector2d>& c, const Eigen::Vector2d& centre) {
  std::vector<LatticeHole> holes;
  if (c.size() < 5) return holes;
  const double pitch = median_nearest_distance(c);
  if (!(pitch > 0)) return holes;
  const BlobIndex index(c, pitch);

  // Seed: the blob nearest the centre whose neighbours within 1.3 pitch are exactly a square cross.
  std::vector<int> order(c.size());
  for (size_t k = 0; k < c.size(); ++k) order[k] = int(k);
  std::sort(order.begin(), order.end(), [&](int a, int b) { return (c[size_t(a)] - centre).norm() < (c[size_t(b)] - centre).norm(); });
  int seed = -1;
  Eigen::Vector2d a, b;
  for (size_t s = 0; s < std::min<size_t>(order.size(), 100) && seed < 0; ++s) {
    const int k = order[s];
    const std::vector<int> near = index.within(c[size_t(k)], 1.3 * pitch, k);
    if (near.size() != 4) continue;
    std::vector<Eigen::Vector2d> v;
    for (int n : near) v.push_back(c[size_t(n)] - c[size_t(k)]);
    auto best = [&](const Eigen::Vector2d& dir) {
      return *std::max_element(v.begin(), v.end(), [&](const auto& p, const auto& q) { return p.dot(dir) < q.dot(dir); });
    };
    a = best({1, 0}), b = best({0, 1});
    const Eigen::Vector2d ma = best({-1, 0}), mb = best({0, -1});
    const bool square = std::abs(a.dot(b)) < 0.3 * a.norm() * b.norm() && (a + ma).norm() < 0.3 * a.norm() &&
                        (b + mb).norm() < 0.3 * b.norm() && std::abs(a.norm() - b.norm()) < 0.25 * a.norm();
    if (square) seed = k;
  }
  if (seed < 0) return holes;

  NodeMap nodes;
  std::vector<bool> taken(c.size(), false);
  auto assign = [&](int i, int j, int blob) {
    nodes[{i, j}] = int(holes.size());
    holes.push_back({i, j, blob});
    taken[size_t(blob)] = true;
  };
  assign(0, 0, seed);
  for (const auto& [di, dj, v] : {std::tuple{1, 0, a}, {-1, 0, Eigen::Vector2d(-a)}, {0, 1, b}, {0, -1, Eigen::Vector2d(-b)}}) {
    const int blob = index.nearest(c[size_t(seed)] + v, 0.3 * pitch, taken);
    if (blob >= 0) assign(di, dj, blob);
  }

  // Bridging a gap: a cubic in lattice coordinates through every indexed hole. A local fit on one
  // side of an occluder's band extrapolates the intensifier's pincushion badly over ten pitches; the
  // global smooth field does not (and assumes no small distortion, only a smooth one).
  auto global_field = [&](PolynomialMap2& field) {
    if (holes.size() < 40) return false;
    std::vector<Eigen::Vector2d> from, to;
    double extent = 1;
    for (const auto& h : holes) {
      from.emplace_back(h.i, h.j), to.push_back(c[size_t(h.blob)]);
      extent = std::max({extent, std::abs(double(h.i)), std::abs(double(h.j))});
    }
    field = PolynomialMap2::fit(from, to, 3, Eigen::Vector2d::Zero(), extent);
    return true;
  };

  auto grow = [&](int reach) {
    PolynomialMap2 field;
    const bool have_field = reach > 2 && global_field(field);
    std::set<std::pair<int, int>> frontier;
    for (const auto& [ij, h] : nodes)
      for (int dj = -reach; dj <= reach; ++dj)
        for (int di = -reach; di <= reach; ++di)
          if (std::max(std::abs(di), std::abs(dj)) == reach || reach == 1)
            if (!nodes.count({ij.first + di, ij.second + dj})) frontier.insert({ij.first + di, ij.second + dj});
    std::vector<std::pair<int, int>> todo(frontier.begin(), frontier.end());
    std::sort(todo.begin(), todo.end(), [](const auto& p, const auto& q) {
      return std::abs(p.first) + std::abs(p.second) < std::abs(q.first) + std::abs(q.second);
    });
    bool grew = false;
    for (const auto& [i, j] : todo) {
      if (nodes.count({i, j})) continue;
      Eigen::Vector2d predicted;
      double local_pitch = 0;
      if (!have_field && !predict_node(holes, c, i, j, reach == 1 ? 2 : reach + 4, reach > 2, predicted, local_pitch)) continue;
      if (have_field) {
        predicted = field(Eigen::Vector2d(i, j));
        const Eigen::Vector2d di = field(Eigen::Vector2d(i + 0.5, j)) - field(Eigen::Vector2d(i - 0.5, j));
        const Eigen::Vector2d dj = field(Eigen::Vector2d(i, j + 0.5)) - field(Eigen::Vector2d(i, j - 0.5));
        local_pitch = std::sqrt(std::abs(di.x() * dj.y() - di.y() * dj.x()));
      }
      const int blob = index.nearest(predicted, 0.3 * local_pitch, taken);
      if (blob < 0) continue;
      assign(i, j, blob);
      grew = true;
    }
    return grew;
  };
  // Gaps up to 15 pitches wide (an occluder hiding 40 % of a 35-hole field) are bridged.
  for (int reach = 1; reach <= 15;) reach = grow(reach) ? 1 : reach + 1;
  return holes;
}

}  // namespace fluoro
