#include "pipelines/calibration/fiducial_matching.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/calib3d.hpp>

#include "engine/camera.hpp"
#include "engine/error.hpp"

namespace fluoro {
namespace {

// One-to-one pairing of projected fiducials with detections within `tol`, nearest pairs first.
std::vector<int> pair_nearest(const std::vector<Eigen::Vector2d>& projected,
                              const std::vector<Eigen::Vector2d>& detections, double tol, int* count) {
  struct Candidate {
    double d;
    int model, det;
  };
  std::vector<Candidate> c;
  for (int m = 0; m < int(projected.size()); ++m) {
    if (!projected[m].allFinite()) continue;
    for (int d = 0; d < int(detections.size()); ++d) {
      const double dist = (projected[m] - detections[d]).norm();
      if (dist < tol) c.push_back({dist, m, d});
    }
  }
  std::sort(c.begin(), c.end(), [](const Candidate& a, const Candidate& b) { return a.d < b.d; });
  std::vector<int> of(projected.size(), -1);
  std::vector<bool> used(detections.size(), false);
  *count = 0;
  for (const auto& k : c)
    if (of[k.model] < 0 && !used[k.det]) of[k.model] = k.det, used[k.det] = true, ++*count;
  return of;
}

bool coplanar(const std::vector<Eigen::Vector3d>& X) {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& p : X) mean += p;
  mean /= double(X.size());
  Eigen::Matrix3d s = Eigen::Matrix3d::Zero();
  for (const auto& p : X) s += (p - mean) * (p - mean).transpose();
  const Eigen::Vector3d ev = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(s).eigenvalues();
  return ev(0) <= 1e-6 * ev(2);
}

// The largest number of points within 0.5 mm of one plane through three of them.
int most_in_one_plane(const std::vector<Eigen::Vector3d>& X) {
  const int n = int(X.size());
  int best = std::min(n, 3);
  for (int a = 0; a < n; ++a)
    for (int b = a + 1; b < n; ++b)
      for (int c = b + 1; c < n; ++c) {
        const Eigen::Vector3d normal = (X[b] - X[a]).cross(X[c] - X[a]);
        if (normal.norm() < 1e-9) continue;
        const Eigen::Vector3d u = normal.normalized();
        int in = 0;
        for (const auto& p : X) in += std::abs(u.dot(p - X[a])) < 0.5 ? 1 : 0;
        best = std::max(best, in);
      }
  return best;
}

// True when P decomposes into K with |skew| < 5 % of the focal length and an aspect ratio within
// 20 % of 1 (video-digitised intensifier images are not quite square), and the principal point
// in the image.
// Every paired fiducial must also lie in front of the source.
bool physical_camera(const Projection& P, const std::vector<Eigen::Vector3d>& model, const std::vector<int>& of,
                     int width, int height) {
  try {
    const PinholeCamera c = camera_from_projection(P, 1, 1, "hypothesis");
    const double fx = c.K(0, 0), fy = c.K(1, 1);
    if (c.K(0, 2) < 0 || c.K(0, 2) > width || c.K(1, 2) < 0 || c.K(1, 2) > height) return false;
    for (size_t i = 0; i < model.size(); ++i)
      if (of[i] >= 0 && !((c.R * model[i] + c.t).z() > 0)) return false;
    return std::abs(c.K(0, 1)) < 0.05 * fx && fx < 1.2 * fy && fy < 1.2 * fx;
  } catch (const InputError&) {
    return false;
  }
}

// How many projected fiducials have a detection within tol (not one-to-one: a quick screen).
int count_near(const std::vector<Eigen::Vector2d>& projected, const std::vector<Eigen::Vector2d>& detections,
               double tol) {
  const double t2 = tol * tol;
  int count = 0;
  for (const auto& p : projected) {
    if (!p.allFinite()) continue;
    for (const auto& d : detections)
      if ((p - d).squaredNorm() < t2) {
        ++count;
        break;
      }
  }
  return count;
}

std::vector<Eigen::Vector2d> project_all(const Projection& P, const std::vector<Eigen::Vector3d>& model) {
  std::vector<Eigen::Vector2d> out;
  out.reserve(model.size());
  for (const auto& X : model) out.push_back(project_with(P, X));
  return out;
}

// From a rough projection, alternate "pair within tol, refit the DLT" while the tolerance
// tightens; the refit absorbs the hypothesis' wrong focal length and principal point.
std::optional<FiducialMatching> verify(const Projection& rough, const std::vector<Eigen::Vector3d>& model,
                                       const std::vector<Eigen::Vector2d>& detections, double loose, double tight,
                                       double max_rms, int width, int height, int min_pairs,
                                       MatchingDiagnostics* diagnostics) {
  Projection P = rough;
  const double tols[] = {loose, 0.5 * (loose + tight), tight, tight};
  FiducialMatching m;
  for (double tol : tols) {
    int count = 0;
    const std::vector<int> of = pair_nearest(project_all(P, model), detections, tol, &count);
    if (count < 6) return std::nullopt;
    std::vector<Eigen::Vector3d> X;
    std::vector<Eigen::Vector2d> x;
    for (size_t i = 0; i < of.size(); ++i)
      if (of[i] >= 0) X.push_back(model[i]), x.push_back(detections[size_t(of[i])]);
    const auto fit = projection_dlt(X, x);
    if (!fit) {
      if (diagnostics && coplanar(X)) diagnostics->coplanar_pairs_seen = true;
      return std::nullopt;
    }
    P = *fit;
    m.detection_of = of;
    m.pairs = count;
  }
  // The final pairs under the final DLT.
  int count = 0;
  m.detection_of = pair_nearest(project_all(P, model), detections, tight, &count);
  m.pairs = count;
  if (count < min_pairs) return std::nullopt;
  double ss = 0;
  for (size_t i = 0; i < model.size(); ++i)
    if (m.detection_of[i] >= 0) ss += (project_with(P, model[i]) - detections[size_t(m.detection_of[i])]).squaredNorm();
  m.rms_px = std::sqrt(ss / count);
  m.P = P;
  // With few pairs a DLT (11 degrees of freedom) fits a wrong pairing too; its camera then has a
  // large skew or an absurd aspect ratio. A real detector's pixels are near square and unskewed.
  if (m.rms_px > max_rms || !physical_camera(P, model, m.detection_of, width, height)) return std::nullopt;
  // Pairs that lie in one plane but for one or two fix P with (next to) no redundancy: the plane's
  // homography takes 8 of P's 11 degrees of freedom, two more points pin the rest, and any two
  // detections can be explained so. Demand 3 fiducials off the plane holding the most pairs.
  std::vector<Eigen::Vector3d> paired;
  for (size_t i = 0; i < model.size(); ++i)
    if (m.detection_of[i] >= 0) paired.push_back(model[i]);
  if (int(paired.size()) - most_in_one_plane(paired) < 3) {
    if (diagnostics) diagnostics->coplanar_pairs_seen = true;
    return std::nullopt;
  }
  return m;
}

// Basis triples of fiducials for P3P: large triangles first, each new one sharing at most one
// fiducial with those before, so an undetected fiducial does not sink every basis.
std::vector<std::array<int, 3>> basis_triples(const std::vector<Eigen::Vector3d>& model, int wanted) {
  struct T {
    double area;
    std::array<int, 3> idx;
  };
  std::vector<T> all;
  const int n = int(model.size());
  for (int a = 0; a < n; ++a)
    for (int b = a + 1; b < n; ++b)
      for (int c = b + 1; c < n; ++c)
        all.push_back({0.5 * (model[b] - model[a]).cross(model[c] - model[a]).norm(), {a, b, c}});
  std::sort(all.begin(), all.end(), [](const T& x, const T& y) { return x.area > y.area; });
  std::vector<std::array<int, 3>> out;
  for (const auto& t : all) {
    if (int(out.size()) >= wanted) break;
    bool fresh = true;
    for (const auto& o : out) {
      int shared = 0;
      for (int i : t.idx) shared += int(std::count(o.begin(), o.end(), i));
      if (shared > 1) fresh = false;
    }
    if (fresh) out.push_back(t.idx);
  }
  return out;
}

}  // namespace

std::optional<FiducialMatching> match_fiducials(const std::vector<Eigen::Vector3d>& model,
                                                const std::vector<Eigen::Vector2d>& detections,
                                                int width, int height, const MatchingParams& params,
                                                MatchingDiagnostics* diagnostics) {
  const int n = int(model.size()), m = int(detections.size());
  if (n < 6 || m < 6) return std::nullopt;
  // Loose tolerance: well under half the typical spacing of the detections, so a rough pose
  // cannot pair a fiducial with its neighbour's ball.
  std::vector<double> nn;
  for (int i = 0; i < m; ++i) {
    double best = std::numeric_limits<double>::infinity();
    for (int j = 0; j < m; ++j)
      if (i != j) best = std::min(best, (detections[i] - detections[j]).norm());
    nn.push_back(best);
  }
  std::nth_element(nn.begin(), nn.begin() + m / 2, nn.end());
  const double loose = std::max(3.0 * params.tight_tolerance_px, 0.35 * nn[size_t(m / 2)]);
  // Pairing 80 % of what can be paired at the tight tolerance: no wrong pairing of an asymmetric
  // pattern comes near that, so the search stops there.
  const int enough = std::max(6, int(0.8 * std::min(n, m)));
  // A pairing must explain most of what could be paired: with many hypotheses tried, a handful of
  // pairs of a wrong one can fall within the tolerance by chance.
  const int min_pairs = std::max(6, int(std::ceil(params.min_paired_fraction * std::min(n, m))));

  const double size = std::max(width, height);
  // A C-arm's focal length first (2 to 4 image sizes), then the rest of the family: with the focal
  // length as the outer loop, a typical image is paired after a sixth of the hypotheses.
  const double focal_factors[] = {2.8, 2.0, 4.0, 1.4, 5.6, 1.0};
  std::optional<FiducialMatching> best;
  std::vector<cv::Point3d> obj(3);
  std::vector<cv::Point2d> img(3);
  std::vector<cv::Mat> rvecs, tvecs;
  // Detection triples, largest image triangle first: the basis is the phantom's largest triangle,
  // whose image is large too, so the true triple comes early and the search stops there.
  struct DetTriple {
    double area;
    int a, b, c;
  };
  std::vector<DetTriple> triples;
  for (int a = 0; a < m; ++a)
    for (int b = a + 1; b < m; ++b)
      for (int c = b + 1; c < m; ++c) {
        const Eigen::Vector2d u = detections[b] - detections[a], v = detections[c] - detections[a];
        triples.push_back({0.5 * std::abs(u.x() * v.y() - u.y() * v.x()), a, b, c});
      }
  std::sort(triples.begin(), triples.end(), [](const DetTriple& x, const DetTriple& y) { return x.area > y.area; });
  const int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};

  std::vector<Eigen::Vector2d> projected(model.size());
  for (const auto& tri : basis_triples(model, params.max_model_triples)) {
    for (int k = 0; k < 3; ++k) obj[k] = cv::Point3d(model[tri[k]].x(), model[tri[k]].y(), model[tri[k]].z());
    for (double ff : focal_factors) {
      for (const DetTriple& t : triples) {
        // The basis is the phantom's largest triangle: unless the view is nearly edge-on to it, its
        // image is not tiny beside the largest triangle of detections.
        if (t.area < 0.1 * triples.front().area) break;
        const int abc[3] = {t.a, t.b, t.c};
        for (const auto& perm : perms) {
          for (int k = 0; k < 3; ++k) img[k] = cv::Point2d(detections[abc[perm[k]]].x(), detections[abc[perm[k]]].y());
          const double f = ff * size;
          const cv::Matx33d K(f, 0, 0.5 * (width - 1), 0, f, 0.5 * (height - 1), 0, 0, 1);
          rvecs.clear();
          tvecs.clear();
          int sols = 0;
          try {
            sols = cv::solveP3P(obj, img, K, cv::noArray(), rvecs, tvecs, cv::SOLVEPNP_AP3P);
          } catch (const cv::Exception&) {
            continue;  // a degenerate triple of pixels
          }
          for (int s = 0; s < sols; ++s) {
            cv::Matx33d Rcv;
            cv::Rodrigues(rvecs[size_t(s)], Rcv);
            Projection rt;
            for (int i = 0; i < 3; ++i) {
              for (int j = 0; j < 3; ++j) rt(i, j) = Rcv(i, j);
              rt(i, 3) = tvecs[size_t(s)].at<double>(i);
            }
            Eigen::Matrix3d Ke;
            Ke << f, 0, 0.5 * (width - 1), 0, f, 0.5 * (height - 1), 0, 0, 1;
            const Projection P = Ke * rt;
            for (size_t i = 0; i < model.size(); ++i) projected[i] = project_with(P, model[i]);
            const int count = count_near(projected, detections, loose);
            if (count < 6 || (best && count < best->pairs / 2)) continue;
            auto v = verify(P, model, detections, loose, params.tight_tolerance_px, params.max_rms_px, width, height,
                          min_pairs, diagnostics);
            if (v && (!best || v->pairs > best->pairs || (v->pairs == best->pairs && v->rms_px < best->rms_px)))
              best = v;
            if (best && best->pairs >= enough) return best;
          }
        }
      }
    }
  }
  return best;
}

}  // namespace fluoro
