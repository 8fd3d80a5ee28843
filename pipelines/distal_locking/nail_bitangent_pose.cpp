#include "pipelines/distal_locking/nail_bitangent_pose.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <opencv2/calib3d.hpp>
#include <vector>

namespace fluoro {
namespace {

// The ellipse's shape matrix: x in it iff (x - c)^T M^-1 (x - c) <= 1.
Eigen::Matrix2d shape(const HoleEllipse& e) {
  const double t = e.angle_deg * std::numbers::pi / 180.0;
  const Eigen::Vector2d u(std::cos(t), std::sin(t)), v(-u.y(), u.x());
  return 0.25 * e.major_px * e.major_px * u * u.transpose() + 0.25 * e.minor_px * e.minor_px * v * v.transpose();
}

}  // namespace

bool outer_bitangent_points(const HoleEllipse& a, const HoleEllipse& b, Eigen::Vector2d points[4]) {
  const Eigen::Matrix2d Ma = shape(a), Mb = shape(b);
  // A line n . x = h touches both on the same side when their support functions agree:
  // f(phi) = h_a(n) - h_b(n) = 0, h(n) = n . c + sqrt(n^T M n). Two roots, near the normals of the
  // centres' line.
  const auto f = [&](double phi) {
    const Eigen::Vector2d n(std::cos(phi), std::sin(phi));
    return n.dot(a.centre_px) + std::sqrt(n.dot(Ma * n)) - n.dot(b.centre_px) - std::sqrt(n.dot(Mb * n));
  };
  const Eigen::Vector2d e = (b.centre_px - a.centre_px).normalized(), left(-e.y(), e.x());
  std::vector<double> roots;
  constexpr int kSteps = 720;
  for (int i = 0; i < kSteps; ++i) {
    double lo = 2 * std::numbers::pi * i / kSteps, hi = 2 * std::numbers::pi * (i + 1) / kSteps;
    double flo = f(lo);
    if ((flo > 0) == (f(hi) > 0)) continue;
    for (int k = 0; k < 60; ++k) {
      const double mid = 0.5 * (lo + hi);
      if ((f(mid) > 0) == (flo > 0)) lo = mid, flo = f(mid);
      else hi = mid;
    }
    roots.push_back(0.5 * (lo + hi));
  }
  if (roots.size() != 2) return false;
  for (double phi : roots) {
    const Eigen::Vector2d n(std::cos(phi), std::sin(phi));
    const int side = n.dot(left) > 0 ? 0 : 2;
    points[side] = a.centre_px + Ma * n / std::sqrt(n.dot(Ma * n));
    points[side + 1] = b.centre_px + Mb * n / std::sqrt(n.dot(Mb * n));
  }
  return (roots.size() == 2) && (std::cos(roots[0]) * std::cos(roots[1]) + std::sin(roots[0]) * std::sin(roots[1]) < 0);
}

NailPoseEstimate bitangent_nail_pose(const NailDetection& det, const NailModel& nail, const Eigen::Matrix3d& K,
                                     const Eigen::Vector3d& guide_x, const Eigen::Vector3d& guide_z) {
  NailPoseEstimate out;
  if (det.holes.size() != 2 || nail.holes.size() != 2) {
    out.failure_reason = "the bitangent pose needs two holes";
    return out;
  }
  Eigen::Vector2d p[4];
  if (!outer_bitangent_points(det.holes[0], det.holes[1], p)) {
    out.failure_reason = "no two outer bitangents";
    return out;
  }
  // Model holes in the order of their x, as the detections along the band (the 180-degree turn
  // about z that swaps them is one of the nail's symmetries, resolved below by the guide).
  std::vector<NailHole> holes = nail.holes;
  std::sort(holes.begin(), holes.end(), [](const NailHole& x, const NailHole& y) { return x.center_mm.x() < y.center_mm.x(); });
  std::vector<cv::Point3d> model;
  for (double s : {1.0, -1.0})
    for (const auto& h : holes) model.emplace_back(h.center_mm.x(), s * 0.5 * h.diameter_mm, 0.0);
  std::vector<cv::Point2d> image;
  for (const auto& q : p) image.emplace_back(q.x(), q.y());
  cv::Mat Kcv = (cv::Mat_<double>(3, 3) << K(0, 0), K(0, 1), K(0, 2), K(1, 0), K(1, 1), K(1, 2), K(2, 0), K(2, 1), K(2, 2));
  std::vector<cv::Mat> rvecs, tvecs;
  std::vector<double> errors;
  cv::solvePnPGeneric(model, image, Kcv, cv::noArray(), rvecs, tvecs, false, cv::SOLVEPNP_IPPE, cv::noArray(), cv::noArray(), errors);
  if (rvecs.empty()) {
    out.failure_reason = "IPPE found no pose";
    return out;
  }
  // IPPE's two planar poses: the better reprojection unless within 10 % (four points of ellipses
  // read at a pixel's fraction rarely tell them apart), then the one whose hole axes are nearest
  // the guide's.
  size_t best = 0;
  double best_score = -HUGE_VAL;
  const double best_error = *std::min_element(errors.begin(), errors.end());
  for (size_t i = 0; i < rvecs.size(); ++i) {
    if (errors.size() == rvecs.size() && errors[i] > 1.1 * best_error + 1e-9) continue;
    cv::Matx33d R;
    cv::Rodrigues(rvecs[i], R);
    CameraPose T = CameraPose::Identity();
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) T.linear()(r, c) = R(r, c);
      T.translation()(r) = tvecs[i].at<double>(r);
    }
    const CameraPose S = nearest_symmetric_pose(T, nail, guide_x, guide_z);
    const double score = S.linear().col(2).dot(guide_z);
    if (score > best_score) best_score = score, best = i, out.T_camera_nail = S;
  }
  (void)best;
  out.ok = true;
  return out;
}

}  // namespace fluoro
