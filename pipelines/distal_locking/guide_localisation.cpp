#include "pipelines/distal_locking/guide_localisation.hpp"

#include "pipelines/distal_locking/guide_pairing_check.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>

namespace fluoro {
namespace {

std::vector<Eigen::Vector2d> project_all(const Eigen::Matrix3d& K, const CameraPose& pose,
                                         const std::vector<Eigen::Vector3d>& X) {
  std::vector<Eigen::Vector2d> out;
  out.reserve(X.size());
  for (const auto& p : X) out.push_back(project_pose(K, pose, p));
  return out;
}

// The k nearest other points of each point (indices), nearest first.
std::vector<std::vector<int>> nearest(const std::vector<Eigen::Vector2d>& p, int k) {
  std::vector<std::vector<int>> out(p.size());
  for (size_t i = 0; i < p.size(); ++i) {
    std::vector<std::pair<double, int>> d;
    for (size_t j = 0; j < p.size(); ++j)
      if (j != i) d.push_back({(p[i] - p[j]).squaredNorm(), int(j)});
    const size_t n = std::min(d.size(), size_t(k));
    std::partial_sort(d.begin(), d.begin() + long(n), d.end());
    for (size_t j = 0; j < n; ++j) out[i].push_back(d[j].second);
  }
  return out;
}

// How many model spheres the pose puts inside the image (all in front of the source when the
// image's size is not known).
int spheres_in_image(const Eigen::Matrix3d& K, const CameraPose& pose, const std::vector<Eigen::Vector3d>& model,
                     const Eigen::Vector2i& size) {
  int n = 0;
  for (const auto& X : model) {
    const Eigen::Vector2d p = project_pose(K, pose, X);
    n += p.allFinite() && (size.x() <= 0 || (p.x() >= 0 && p.y() >= 0 && p.x() <= size.x() - 1 && p.y() <= size.y() - 1));
  }
  return n;
}

// Two poses of the guide that are one answer: within 1 degree and 3 mm.
bool same_pose(const CameraPose& a, const CameraPose& b) {
  const Eigen::AngleAxisd d(a.linear().transpose() * b.linear());
  return std::abs(d.angle()) < 1.0 * 3.14159265358979323846 / 180.0 && (a.translation() - b.translation()).norm() < 3.0;
}

struct Verified {
  CameraPose pose;
  std::vector<int> of;
  int pairs = 0;
  double rms = 0;
};

// From a rough pose: pair within a shrinking tolerance and refit the pose each time.
std::optional<Verified> verify(const Eigen::Matrix3d& K, CameraPose pose, const std::vector<Eigen::Vector3d>& model,
                               const std::vector<Eigen::Vector2d>& det, double loose, double tight) {
  Verified v;
  const double tols[] = {loose, 0.5 * (loose + tight), tight, tight};
  for (double tol : tols) {
    int count = 0;
    const std::vector<int> of = pair_nearest(project_all(K, pose, model), det, tol, &count);
    if (count < 4) return std::nullopt;
    std::vector<Eigen::Vector3d> X;
    std::vector<Eigen::Vector2d> x;
    for (size_t i = 0; i < of.size(); ++i)
      if (of[i] >= 0) X.push_back(model[i]), x.push_back(det[size_t(of[i])]);
    pose = refine_pose(K, pose, X, x);
    if (!(pose.translation().z() > 0)) return std::nullopt;
  }
  int count = 0;
  v.of = pair_nearest(project_all(K, pose, model), det, tight, &count);
  v.pairs = count;
  // The pose from the pairs that agree best (guide_pairing_check.hpp).
  int outliers = 0;
  pose = refit_without_outliers(K, pose, model, det, v.of, 6, &outliers);
  v.pose = pose;
  double ss = 0;
  for (size_t i = 0; i < model.size(); ++i)
    if (v.of[i] >= 0) ss += (project_pose(K, pose, model[i]) - det[size_t(v.of[i])]).squaredNorm();
  v.rms = count ? std::sqrt(ss / count) : 0;
  return v;
}

}  // namespace

GuideLocalisation match_guide(const DrillGuideModel& guide, const std::vector<Eigen::Vector2d>& det,
                              const Eigen::Matrix3d& K, const GuideMatchingParams& params) {
  GuideLocalisation out;
  const auto& model = guide.spheres_mm;
  const int n = int(model.size()), m = int(det.size());
  if (m < params.min_pairs) {
    out.failure_reason = "too few spheres matched: " + std::to_string(m) + " dark circles found";
    return out;
  }
  // Model bases: each sphere with its two nearest neighbours (a small triangle survives occlusion
  // far better than a large one); detection bases: each detection with two of its 6 nearest.
  std::vector<std::array<int, 3>> bases;
  for (int a = 0; a < n; ++a) {
    std::vector<std::pair<double, int>> d;
    for (int b = 0; b < n; ++b)
      if (b != a) d.push_back({(model[size_t(a)] - model[size_t(b)]).norm(), b});
    std::sort(d.begin(), d.end());
    // The second neighbour must leave a triangle, not a line.
    for (size_t j = 1; j < d.size(); ++j) {
      const Eigen::Vector3d u = model[size_t(d[0].second)] - model[size_t(a)], w = model[size_t(d[j].second)] - model[size_t(a)];
      if (u.cross(w).norm() > 0.3 * u.norm() * w.norm()) {
        bases.push_back({a, d[0].second, d[j].second});
        break;
      }
    }
  }
  const auto near = nearest(det, 6);
  std::vector<double> nn;
  for (int i = 0; i < m; ++i)
    if (!near[size_t(i)].empty()) nn.push_back((det[size_t(i)] - det[size_t(near[size_t(i)][0])]).norm());
  std::nth_element(nn.begin(), nn.begin() + long(nn.size() / 2), nn.end());
  const double loose = std::max(3.0 * params.tight_tolerance_px, 0.35 * nn[nn.size() / 2]);

  cv::Mat Kcv;
  cv::eigen2cv(K, Kcv);
  // Screen every hypothesis by a quick count at the loose tolerance; verify the best few.
  struct Hyp {
    int count;
    CameraPose pose;
  };
  std::vector<cv::Point3d> obj(3);
  std::vector<cv::Point2d> img(3);
  std::vector<cv::Mat> rvecs, tvecs;
  std::optional<Verified> best, second;
  int agreeing = 0;  // verified hypotheses from different bases that found the best pairing
  const double l2 = loose * loose;
  for (const auto& b : bases) {
    std::vector<Hyp> hyps;
    for (int k = 0; k < 3; ++k) obj[size_t(k)] = cv::Point3d(model[size_t(b[size_t(k)])].x(), model[size_t(b[size_t(k)])].y(), model[size_t(b[size_t(k)])].z());
    for (int a = 0; a < m; ++a)
      for (size_t ii = 0; ii < near[size_t(a)].size() && ii < 4; ++ii)
        for (int j : near[size_t(a)]) {
          const int i = near[size_t(a)][ii];
          if (i == j) continue;
          const int idx[3] = {a, i, j};
          for (int k = 0; k < 3; ++k) img[size_t(k)] = cv::Point2d(det[size_t(idx[k])].x(), det[size_t(idx[k])].y());
          rvecs.clear();
          tvecs.clear();
          int sols = 0;
          try {
            sols = cv::solveP3P(obj, img, Kcv, cv::noArray(), rvecs, tvecs, cv::SOLVEPNP_AP3P);
          } catch (const cv::Exception&) {
            continue;
          }
          for (int s = 0; s < sols; ++s) {
            cv::Matx33d Rcv;
            cv::Rodrigues(rvecs[size_t(s)], Rcv);
            CameraPose pose = CameraPose::Identity();
            for (int r = 0; r < 3; ++r) {
              for (int c = 0; c < 3; ++c) pose.linear()(r, c) = Rcv(r, c);
              pose.translation()(r) = tvecs[size_t(s)].at<double>(r);
            }
            if (!(pose.translation().z() > 0)) continue;
            int count = 0;
            for (const auto& X : model) {
              const Eigen::Vector2d p = project_pose(K, pose, X);
              if (!p.allFinite()) continue;
              for (const auto& d : det)
                if ((p - d).squaredNorm() < l2) {
                  ++count;
                  break;
                }
            }
            if (count >= std::max(4, params.min_pairs / 2)) hyps.push_back({count, pose});
          }
        }
    // Verify this basis' best few hypotheses.
    std::sort(hyps.begin(), hyps.end(), [](const Hyp& x, const Hyp& y) { return x.count > y.count; });
    bool agreed = false;
    for (size_t h = 0; h < hyps.size() && h < 4; ++h) {
      const auto v = verify(K, hyps[h].pose, model, det, loose, params.tight_tolerance_px);
      if (!v) continue;
      // Pairings whose poses agree (a clutter ball taken for a sphere or not) are the same
      // answer; the one with more pairs, then the smaller residual, stands for it.
      if (best && same_pose(v->pose, best->pose)) {
        agreed = true;
        if (v->pairs > best->pairs || (v->pairs == best->pairs && v->rms < best->rms)) best = v;
      } else if (!best || v->pairs > best->pairs) {
        if (best) second = best;
        best = v;
        agreeing = 0;
        agreed = true;
      } else if (!second || v->pairs > second->pairs) {
        second = v;
      }
    }
    agreeing += agreed ? 1 : 0;
    // Three bases (three different triples of spheres) found the same pairing: the search stops,
    // if that pairing explains at least half of the spheres its pose puts in the image. A pairing
    // of 7 of 28 visible spheres (a pose 24 degrees off) once stopped the search here, three bases
    // agreeing on it, before any basis had tried the true pose (docs/distal_locking.md).
    if (best && best->pairs >= params.min_pairs && agreeing >= 3 &&
        best->pairs >= kMinExplainedFraction * spheres_in_image(K, best->pose, model, params.image_size))
      break;
  }
  if (!best || best->pairs < params.min_pairs) {
    out.failure_reason = "too few spheres matched: the best pairing explains " + std::to_string(best ? best->pairs : 0) +
                         " of the " + std::to_string(m) + " dark circles found (" + std::to_string(params.min_pairs) +
                         " needed)";
    return out;
  }
  out.second_best_pairs = second ? second->pairs : 0;
  if (second && second->pairs >= best->pairs) {
    out.failure_reason = "ambiguous sphere pairing: two pairings with different poses explain " + std::to_string(best->pairs) +
                         " spheres each";
    return out;
  }
  // The pairing the final pose itself explains, or a flag (guide_pairing_check.hpp).
  const CheckedPairing checked = check_guide_pairing(K, model, det, best->pose, params.tight_tolerance_px, params.min_pairs,
                                                     params.image_size, 0.5 * guide.sphere_diameter_mm);
  out.T_camera_guide = checked.pose;
  out.detection_of = checked.detection_of;
  out.outlier_pairs = checked.outliers;
  if (!checked.ok) {
    out.failure_reason = checked.failure_reason;
    return out;
  }
  out.ok = true;
  for (int i = 0; i < n; ++i)
    if (checked.detection_of[size_t(i)] >= 0) {
      out.matched_ids.push_back(i);
      out.max_px = std::max(out.max_px, (project_pose(K, checked.pose, model[size_t(i)]) - det[size_t(checked.detection_of[size_t(i)])]).norm());
    }
  out.rms_px = checked.rms_px;
  return out;
}

GuideDetection localise_guide(const Image& xray, const DrillGuideModel& guide, const Eigen::Matrix3d& K) {
  GuideDetection out;
  // Sphere radii in the image between the guide 300 mm and 1500 mm from the source.
  DarkCircleParams p;
  const double f = 0.5 * (K(0, 0) + K(1, 1)), r = 0.5 * guide.sphere_diameter_mm;
  p.min_radius_px = std::max(1.5, 0.8 * f * r / 1500.0);
  p.max_radius_px = std::max(p.min_radius_px + 1.0, 1.2 * f * r / 300.0);
  out.circles = detect_dark_circles(xray, p);
  std::vector<Eigen::Vector2d> centres;
  for (const auto& c : out.circles) centres.push_back(c.centre_px);
  GuideMatchingParams params;
  params.image_size = Eigen::Vector2i(xray.width, xray.height);
  out.localisation = match_guide(guide, centres, K, params);
  return out;
}

}  // namespace fluoro
