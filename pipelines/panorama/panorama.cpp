#include "pipelines/panorama/panorama.hpp"

#include <Eigen/Dense>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <opencv2/imgproc.hpp>

#include "engine/ellipse_erosion.hpp"
#include "engine/error.hpp"
#include "engine/field_of_view.hpp"
#include "pipelines/panorama/contour_fit.hpp"
#include "pipelines/panorama/plane_realignment.hpp"

namespace fluoro {
namespace {

// The ruler's geometry in the frame's pixels, for the overlay: the thread's stretch inside the
// field of view and the graduations' feet on it.
void record_ruler(const RulerFrame& r, const cv::Mat& mask, PanoramaFrame& f) {
  const RulerThread& t = r.thread;
  const Eigen::Vector2d foot = t.centre + t.offset_px * t.normal(), e = t.direction();
  const auto inside = [&](const Eigen::Vector2d& q) {
    const int u = int(std::lround(q.x())), v = int(std::lround(q.y()));
    return u >= 0 && v >= 0 && u < mask.cols && v < mask.rows && mask.at<uint8_t>(v, u);
  };
  const double reach = std::hypot(mask.cols, mask.rows);
  double first = 1e300, last = -1e300;
  for (double a = -reach; a <= reach; a += 1)
    if (inside(foot + a * e)) first = std::min(first, a), last = std::max(last, a);
  if (last > first) f.thread_px = {foot + first * e, foot + last * e};
  for (double a : r.mark_a) f.graduations_px.push_back(foot + a * e);
  f.thread_normal = t.normal();
  f.thread_width_px = t.width_px;
}

}  // namespace

Panorama align_panorama(const std::vector<cv::Mat>& images, const PanoramaOptions& options,
                        const std::optional<PlaneContours>& contours) {
  std::vector<RulerAlignmentFrame> frames(images.size());
  bool any_ruler = false;
  std::vector<cv::Mat> field_masks(images.size());
  tbb::parallel_for(0, int(images.size()), [&](int i) {
    images[size_t(i)].convertTo(frames[size_t(i)].image, CV_32F);
    // The field once, eroded twice: 3 px for the ruler and the alignment, 2 px for the composition
    // (the same masks as field_of_view_mask(image, 3) and (image, 2)).
    const cv::Mat field = field_of_view_mask(frames[size_t(i)].image, 0);
    const auto erode = [&](int px) { return erode_ellipse(field, 2 * px + 1); };
    frames[size_t(i)].mask = erode(3);
    field_masks[size_t(i)] = erode(2);
    frames[size_t(i)].ruler = find_ruler(frames[size_t(i)].image, frames[size_t(i)].mask);
  });
  for (const auto& f : frames) any_ruler = any_ruler || f.ruler.has_value();
  if (!any_ruler) throw_input_error("--images", "no ruler (a thread with graduations) found in any frame");
  const RulerAlignment a = align_on_ruler(frames, options.alignment);
  Panorama p;
  p.frames.resize(images.size());
  p.field_masks = std::move(field_masks);
  for (size_t i = 0; i < images.size(); ++i) {
    const RulerPlacement& r = a.frames[i];
    PanoramaFrame& f = p.frames[i];
    f.aligned = r.aligned;
    f.confidence = r.confidence;
    if (i > 0 && r.aligned) f.overlap = r.overlap;
    f.rotation_deg = r.rotation_rad * 180 / M_PI;
    f.translation_px = r.translation_px;
    f.graduations = frames[i].ruler ? int(frames[i].ruler->mark_a.size()) : 0;
    f.problem = r.problem;
    if (frames[i].ruler) record_ruler(*frames[i].ruler, frames[i].mask, f);
    p.position_sigma_px = std::max(p.position_sigma_px, r.along_sigma_px);
    if (!r.aligned && p.failure.empty())
      p.failure = "frame " + std::to_string(i) + " cannot be aligned: " + r.problem;
  }
  p.alignment_rms_px = a.residual_rms_px;
  if (!(a.pitch_px > 0)) {
    if (p.failure.empty()) p.failure = "no graduation pitch could be measured";
    return p;
  }
  p.ruler_mm_per_pixel = options.graduation_mm / a.pitch_px;
  const Eigen::Vector2d centre(0.5 * (images[0].cols - 1), 0.5 * (images[0].rows - 1));
  if (contours) {
    const int i = contours->first, j = i + 1;
    char why[256];
    if (!p.frames[size_t(i)].aligned || !p.frames[size_t(j)].aligned) {
      if (p.failure.empty()) {
        std::snprintf(why, sizeof why, "the contours' frames %d and %d are not both aligned", i, j);
        p.failure = why;
      }
    } else {
      const double ri = a.frames[size_t(i)].rotation_rad, rj = a.frames[size_t(j)].rotation_rad;
      const Eigen::Vector2d t = Eigen::Rotation2Dd(-ri).toRotationMatrix() * (a.frames[size_t(j)].translation_px - a.frames[size_t(i)].translation_px);
      const auto s = contour_plane_scale(contours->polylines[0], contours->polylines[1], Eigen::Rotation2Dd(rj - ri).toRotationMatrix(), centre, t);
      if (!s) {
        // No stretch crosses the translation steeply: the least-squares fit over every point,
        // accepted only when it fixes the scale well enough for a length.
        const auto fit = contour_scale_least_squares(contours->polylines[0], contours->polylines[1],
                                                     Eigen::Rotation2Dd(rj - ri).toRotationMatrix(), centre, t);
        if (fit && fit->sigma <= options.max_plane_scale_sigma * fit->scale) {
          p.plane = "contours";
          p.plane_scale = fit->scale;
          p.plane_scale_sigma = fit->sigma;
        } else if (p.failure.empty()) {
          if (fit)
            std::snprintf(why, sizeof why,
                          "the contours run nearly along the translation between their frames: they fix the plane's "
                          "scale only to %.2f %% (standard error; needs %.2f %%)",
                          100 * fit->sigma / fit->scale, 100 * options.max_plane_scale_sigma);
          p.failure = fit ? why : "the contours do not cross the translation between their frames at enough points to fix the plane";
        }
      } else if (s->second <= options.max_plane_scale_sigma * s->first) {
        p.plane = "contours";
        p.plane_scale = s->first;
        p.plane_scale_sigma = s->second;
      } else if (p.failure.empty()) {
        // The crossings' scatter (a trace that wanders, an outline on another edge): the same
        // limit as the fit's, since a length error follows the scale's one for one.
        std::snprintf(why, sizeof why,
                      "the contours' crossings fix the plane's scale only to %.2f %% (standard error; needs %.2f %%)",
                      100 * s->second / s->first, 100 * options.max_plane_scale_sigma);
        p.failure = why;
      }
    }
  }
  p.mm_per_pixel = p.ruler_mm_per_pixel / p.plane_scale;
  p.scale_relative_sigma = std::hypot(a.pitch_sigma_px / a.pitch_px, p.plane_scale_sigma / p.plane_scale);
  // Frame i -> panorama: rotation about the image centre (the principal point after the dewarp),
  // then the translation scaled to the chosen plane; then one offset so every pixel is >= 0.
  std::vector<Eigen::Matrix3d> H(images.size(), Eigen::Matrix3d::Identity());
  Eigen::Vector2d lo(1e300, 1e300), hi(-1e300, -1e300);
  for (size_t i = 0; i < images.size(); ++i) {
    if (!p.frames[i].aligned) continue;
    const Eigen::Matrix2d R = Eigen::Rotation2Dd(a.frames[i].rotation_rad).toRotationMatrix();
    H[i].topLeftCorner<2, 2>() = R;
    H[i].topRightCorner<2, 1>() = centre - R * centre + p.plane_scale * a.frames[i].translation_px;
    const cv::Rect box = cv::boundingRect(frames[i].mask);
    for (const auto& [u, v] : {std::pair{box.x, box.y}, {box.x + box.width - 1, box.y},
                               {box.x, box.y + box.height - 1}, {box.x + box.width - 1, box.y + box.height - 1}}) {
      const Eigen::Vector2d q = (H[i] * Eigen::Vector3d(u, v, 1)).head<2>();
      lo = lo.cwiseMin(q), hi = hi.cwiseMax(q);
    }
  }
  if (hi.x() < lo.x()) return p;
  const Eigen::Vector2d offset(-std::floor(lo.x()), -std::floor(lo.y()));
  p.width = int(std::ceil(hi.x() + offset.x())) + 1;
  p.height = int(std::ceil(hi.y() + offset.y())) + 1;
  for (size_t i = 0; i < images.size(); ++i) {
    if (!p.frames[i].aligned) continue;
    H[i].topRightCorner<2, 1>() += offset;
    p.frames[i].H_panorama_frame = H[i];
  }
  return p;
}

}  // namespace fluoro
