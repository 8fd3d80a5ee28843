// Growing the lattice. Patches grow from seeds: a node next to indexed holes is predicted by an
// affine fit of the indexed holes around it and the nearest free blob within 0.3 of the local pitch
// takes it (a single missing hole is stepped over). Patches cut apart by an occluder's band are then
// joined by hypothesise-and-verify: candidate index offsets, each scored by how well one cubic field
// fits the union. Extrapolating across a band of ten pitches is not trusted to land on the right hole.
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
    visit_buckets(p, radius, [&](int k, double d) {
      if (d < best_d && !taken[size_t(k)]) best_d = d, best = k;
    });
    return best;
  }
  // All blobs within radius of p (other than `self`).
  std::vector<int> within(const Eigen::Vector2d& p, double radius, int self) const {
    std::vector<int> out;
    visit_buckets(p, radius, [&](int k, double d) {
      if (k != self && d < radius) out.push_back(k);
    });
    return out;
  }

 private:
  // Calls f(blob, distance from p) for every blob in the buckets that a disc of `radius` about p
  // touches (a superset of the disc: callers test the distance).
  template <class F>
  void visit_buckets(const Eigen::Vector2d& p, double radius, F&& f) const {
    const long cx = long(std::floor(p.x() / cell_)), cy = long(std::floor(p.y() / cell_));
    const long reach = long(std::ceil(radius / cell_));
    for (long y = cy - reach; y <= cy + reach; ++y)
      for (long x = cx - reach; x <= cx + reach; ++x) {
        const auto it = buckets_.find(pack(x, y));
        if (it == buckets_.end()) continue;
        for (int k : it->second) f(k, (c_[size_t(k)] - p).norm());
      }
  }

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

// Prediction of node (i0, j0) by an affine fit of the indexed holes within `radius` lattice steps,
// with the local pitch there.
bool predict_node(const std::vector<LatticeHole>& holes, const std::vector<Eigen::Vector2d>& c, int i0, int j0,
                  int radius, Eigen::Vector2d& prediction, double& local_pitch) {
  std::vector<std::pair<Eigen::Vector2d, Eigen::Vector2d>> pairs;
  for (const auto& h : holes)
    if (std::abs(h.i - i0) <= radius && std::abs(h.j - j0) <= radius)
      pairs.push_back({Eigen::Vector2d(h.i - i0, h.j - j0), c[size_t(h.blob)]});
  Eigen::Matrix2d A;
  if (!fit_affine(pairs, A, prediction)) return false;  // relative coordinates: t is the prediction
  local_pitch = std::sqrt(std::abs(A.determinant()));
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

namespace {

// A seed: an untaken blob whose neighbours within 1.3 pitch are exactly a square cross; a and b are
// its lattice vectors nearest the image's +x and +y.
struct Seed {
  int blob = -1;
  Eigen::Vector2d a, b;
};

Seed find_seed(const std::vector<Eigen::Vector2d>& c, const std::vector<int>& order, const BlobIndex& index,
               const std::vector<bool>& taken, double pitch) {
  for (const int k : order) {
    if (taken[size_t(k)]) continue;
    const std::vector<int> near = index.within(c[size_t(k)], 1.3 * pitch, k);
    if (near.size() != 4) continue;
    std::vector<Eigen::Vector2d> v;
    for (int n : near) v.push_back(c[size_t(n)] - c[size_t(k)]);
    auto best = [&](const Eigen::Vector2d& dir) {
      return *std::max_element(v.begin(), v.end(), [&](const auto& p, const auto& q) { return p.dot(dir) < q.dot(dir); });
    };
    const Eigen::Vector2d a = best({1, 0}), b = best({0, 1}), ma = best({-1, 0}), mb = best({0, -1});
    const bool square = std::abs(a.dot(b)) < 0.3 * a.norm() * b.norm() && (a + ma).norm() < 0.3 * a.norm() &&
                        (b + mb).norm() < 0.3 * b.norm() && std::abs(a.norm() - b.norm()) < 0.25 * a.norm();
    if (square) return {k, a, b};
  }
  return {};
}

// One connected patch of the lattice grown from a seed: neighbours predicted by local affine fits,
// a single missing hole stepped over (reach 2), never a wider gap.
std::vector<LatticeHole> grow_cluster(const std::vector<Eigen::Vector2d>& c, const BlobIndex& index, const Seed& seed,
                                      std::vector<bool>& taken, double pitch) {
  std::vector<LatticeHole> holes;
  NodeMap nodes;
  auto assign = [&](int i, int j, int blob) {
    nodes[{i, j}] = int(holes.size());
    holes.push_back({i, j, blob});
    taken[size_t(blob)] = true;
  };
  assign(0, 0, seed.blob);
  for (const auto& [di, dj, v] : {std::tuple{1, 0, seed.a}, {-1, 0, Eigen::Vector2d(-seed.a)}, {0, 1, seed.b}, {0, -1, Eigen::Vector2d(-seed.b)}}) {
    const int blob = index.nearest(c[size_t(seed.blob)] + v, 0.3 * pitch, taken);
    if (blob >= 0) assign(di, dj, blob);
  }
  auto grow = [&](int reach) {
    std::set<std::pair<int, int>> frontier;
    for (const auto& [ij, h] : nodes)
      for (int dj = -reach; dj <= reach; ++dj)
        for (int di = -reach; di <= reach; ++di)
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
      if (!predict_node(holes, c, i, j, 2, predicted, local_pitch)) continue;
      const int blob = index.nearest(predicted, 0.3 * local_pitch, taken);
      if (blob < 0) continue;
      assign(i, j, blob);
      grew = true;
    }
    return grew;
  };
  for (int reach = 1; reach <= 2;) reach = grow(reach) ? 1 : reach + 1;
  return holes;
}

// Mean residual of a cubic (lattice -> pixels) through the holes: small for one smooth lattice,
// large when a patch carries the wrong index offset (the cubic cannot fold one pitch into a gap).
double cubic_misfit(const std::vector<LatticeHole>& holes, const std::vector<Eigen::Vector2d>& c) {
  std::vector<Eigen::Vector2d> from, to;
  double extent = 1;
  for (const auto& h : holes) {
    from.emplace_back(h.i, h.j), to.push_back(c[size_t(h.blob)]);
    extent = std::max({extent, std::abs(double(h.i)), std::abs(double(h.j))});
  }
  const PolynomialMap2 field = PolynomialMap2::fit(from, to, 3, Eigen::Vector2d::Zero(), extent);
  double sum = 0;
  for (size_t k = 0; k < from.size(); ++k) sum += (field(from[k]) - to[k]).norm();
  return sum / double(from.size());
}

// Index offset putting `patch` on the lattice of `base`, or false when no offset is clearly best.
// Hypotheses: the node of base's affine field nearest the patch's first hole, and its 9x9 neighbours;
// each is verified by the cubic misfit of the union, and the best must beat the runner-up twice over.
bool patch_offset(const std::vector<LatticeHole>& base, const std::vector<LatticeHole>& patch,
                  const std::vector<Eigen::Vector2d>& c, double pitch, Eigen::Vector2i& offset) {
  std::vector<Eigen::Vector2d> from, to;
  double extent = 1;
  std::set<std::pair<int, int>> used;
  for (const auto& h : base) {
    from.emplace_back(h.i, h.j), to.push_back(c[size_t(h.blob)]);
    extent = std::max({extent, std::abs(double(h.i)), std::abs(double(h.j))});
    used.insert({h.i, h.j});
  }
  // An affine guess: a cubic extrapolated from a narrow patch across a wide band can be off by many
  // pitches, an affine only by the curvature (a few pixels per ten pitches), well inside the 9x9 window.
  const PolynomialMap2 field = PolynomialMap2::fit(from, to, 1, Eigen::Vector2d::Zero(), extent);
  const Eigen::Vector2d target = c[size_t(patch[0].blob)];
  Eigen::Vector2i guess(0, 0);
  double nearest = 1e300;
  const int span = int(extent) + 60;
  for (int j = -span; j <= span; ++j)
    for (int i = -span; i <= span; ++i) {
      const double d = (field(Eigen::Vector2d(i, j)) - target).squaredNorm();
      if (d < nearest) nearest = d, guess = {i, j};
    }
  guess -= Eigen::Vector2i(patch[0].i, patch[0].j);
  double best = 1e300, second = 1e300;
  for (int dj = -4; dj <= 4; ++dj)
    for (int di = -4; di <= 4; ++di) {
      const Eigen::Vector2i o = guess + Eigen::Vector2i(di, dj);
      std::vector<LatticeHole> joined = base;
      bool clash = false;
      for (const auto& h : patch) {
        clash |= used.count({h.i + o.x(), h.j + o.y()}) > 0;
        joined.push_back({h.i + o.x(), h.j + o.y(), h.blob});
      }
      if (clash) continue;  // two holes on one node
      const double misfit = cubic_misfit(joined, c);
      if (misfit < best) second = best, best = misfit, offset = o;
      else second = std::min(second, misfit);
    }
  return best < 0.15 * pitch && best < 0.5 * second;
}

}  // namespace

std::vector<LatticeHole> pair_lattice(const std::vector<Eigen::Vector2d>& c, const Eigen::Vector2d& centre) {
  if (c.size() < 5) return {};
  const double pitch = median_nearest_distance(c);
  if (!(pitch > 0)) return {};
  const BlobIndex index(c, pitch);
  std::vector<int> order(c.size());
  for (size_t k = 0; k < c.size(); ++k) order[k] = int(k);
  std::sort(order.begin(), order.end(), [&](int a, int b) { return (c[size_t(a)] - centre).norm() < (c[size_t(b)] - centre).norm(); });

  // Patches: an occluder's band cuts the lattice into pieces that local growth cannot cross.
  std::vector<bool> taken(c.size(), false);
  std::vector<std::vector<LatticeHole>> patches;
  for (;;) {
    const Seed seed = find_seed(c, order, index, taken, pitch);
    if (seed.blob < 0) break;
    std::vector<LatticeHole> patch = grow_cluster(c, index, seed, taken, pitch);
    if (patch.size() >= 9) patches.push_back(std::move(patch));
  }
  if (patches.empty()) return {};
  std::stable_sort(patches.begin(), patches.end(), [](const auto& p, const auto& q) { return p.size() > q.size(); });

  // The largest patch is the reference; every other joins it only at an offset the data singles out.
  std::vector<LatticeHole> holes = patches[0];
  for (size_t k = 1; k < patches.size(); ++k) {
    Eigen::Vector2i offset;
    if (!patch_offset(holes, patches[k], c, pitch, offset)) continue;  // ambiguous: left out, never guessed
    for (const auto& h : patches[k]) holes.push_back({h.i + offset.x(), h.j + offset.y(), h.blob});
  }
  // Node (0, 0): the indexed hole nearest the centre.
  const auto origin = *std::min_element(holes.begin(), holes.end(), [&](const auto& p, const auto& q) {
    return (c[size_t(p.blob)] - centre).norm() < (c[size_t(q.blob)] - centre).norm();
  });
  for (auto& h : holes) h.i -= origin.i, h.j -= origin.j;
  return holes;
}

}  // namespace fluoro
