#include "pipelines/distal_locking/distal_locking_overlay.hpp"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <string>

#include "engine/display_image.hpp"

namespace fluoro {

std::vector<uint8_t> distal_locking_overlay(const Image& image, const PinholeCamera& camera, const DrillGuideModel& guide,
                                            const NailModel& nail, const DistalLocking& r) {
  cv::Mat rgb = display_rgb(image);
  const auto pt = [](const Eigen::Vector2d& p) { return cv::Point(int(std::lround(p.x())), int(std::lround(p.y()))); };
  const auto& loc = r.guide.localisation;
  std::vector<bool> matched(r.guide.circles.size(), false);
  if (loc.ok)
    for (size_t i = 0; i < loc.detection_of.size(); ++i)
      if (loc.detection_of[i] >= 0) {
        const auto& c = r.guide.circles[size_t(loc.detection_of[i])];
        matched[size_t(loc.detection_of[i])] = true;
        cv::circle(rgb, pt(c.centre_px), int(std::lround(c.radius_px + 2)), cv::Scalar(0, 255, 0), 1, cv::LINE_AA);
        cv::putText(rgb, std::to_string(i), pt(c.centre_px + Eigen::Vector2d(c.radius_px + 2, -c.radius_px - 2)),
                    cv::FONT_HERSHEY_PLAIN, 0.8, cv::Scalar(0, 255, 0), 1, cv::LINE_AA);
      }
  for (size_t k = 0; k < r.guide.circles.size(); ++k)
    if (!matched[k])
      cv::circle(rgb, pt(r.guide.circles[k].centre_px), int(std::lround(r.guide.circles[k].radius_px + 2)),
                 cv::Scalar(255, 220, 0), 1, cv::LINE_AA);
  if (r.nail_detection.band.width_px > 0) {
    const auto& b = r.nail_detection.band;
    const Eigen::Vector2d n(-b.direction.y(), b.direction.x());
    const double L = 2.0 * (image.width + image.height);
    for (double side : {-0.5, 0.5}) {
      const Eigen::Vector2d c = b.axis_point + side * b.width_px * n;
      cv::line(rgb, pt(c - L * b.direction), pt(c + L * b.direction), cv::Scalar(0, 220, 255), 1, cv::LINE_AA);
    }
  }
  for (const auto& h : r.nail_detection.holes)
    cv::ellipse(rgb, cv::RotatedRect(cv::Point2f(float(h.centre_px.x()), float(h.centre_px.y())),
                                     cv::Size2f(float(h.major_px), float(h.minor_px)), float(h.angle_deg)),
                cv::Scalar(255, 0, 255), 1, cv::LINE_AA);
  // Axes 60 mm long, centred on the guide's axis points and on the holes.
  const Eigen::Matrix3d& K = camera.K;
  const auto draw_axis = [&](const Eigen::Isometry3d& T, const Eigen::Vector3d& p, const Eigen::Vector3d& d, const cv::Scalar& col) {
    const Eigen::Vector2d a = project_pose(K, T, p - 30 * d), b = project_pose(K, T, p + 30 * d);
    if (a.allFinite() && b.allFinite()) cv::line(rgb, pt(a), pt(b), col, 1, cv::LINE_AA);
  };
  if (r.guide_ok)
    for (const auto& a : guide.axes) draw_axis(r.T_camera_guide, a.point_mm, a.direction, cv::Scalar(60, 120, 255));
  if (r.nail_ok)
    for (const auto& h : nail.holes) draw_axis(r.T_camera_nail, h.center_mm, Eigen::Vector3d::UnitZ(), cv::Scalar(255, 40, 40));
  return std::vector<uint8_t>(rgb.data, rgb.data + rgb.total() * 3);
}

}  // namespace fluoro
