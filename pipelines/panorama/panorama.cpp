#include "pipelines/panorama/panorama.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <opencv2/imgproc.hpp>

#include "engine/error.hpp"
#include "pipelines/panorama/field_of_view.hpp"

namespace fluoro {
namespace {

Eigen::Matrix2d rotation(double a) {
  Eigen::Matrix2d r;
  r << std::cos(a), -std::sin(a), std::sin(a), std::cos(a);
  return r;
}

double median(std::vector<double> v) {
  const size_t h = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + long(h), v.end());
  return v[h];
}

}  // namespace

std::optional<std::pair<double, double>> contour_plane_scale(const std::vector<Eigen::Vector2d>& first,
                                                             const std::vector<Eigen::Vector2d>& second,
                                                             const Eigen::Matrix2d& rot, const Eigen::Vector2d& centre,
                                                             const Eigen::Vector2d& t) {
  const double len = t.norm();
  if (len < 1 || first.size() < 2) return std::nullopt;
  const Eigen::Vector2d dir = t / len;
  std::vector<double> scales;
  for (const Eigen::Vector2d& q : second) {
    const Eigen::Vector2d p = centre + rot * (q - centre);
    // Crossings of the ray p + mu dir with the first contour; the one nearest mu = |t| (scale 1).
    double best = std::nan("");
    for (size_t k = 0; k + 1 < first.size(); ++k) {
      const Eigen::Vector2d a = first[k], b = first[k + 1], seg = b - a;
      const double den = dir.x() * seg.y() - dir.y() * seg.x();
      // A segment nearly along the translation says nothing about the scale along it.
      if (std::abs(den) < std::sin(10.0 * M_PI / 180) * seg.norm()) continue;
      const Eigen::Vector2d w = a - p;
      const double mu = (w.x() * seg.y() - w.y() * seg.x()) / den;
      const double nu = (w.x() * dir.y() - w.y() * dir.x()) / den;
      if (nu < 0 || nu > 1) continue;
      const double scale = mu / len;
      if (scale < 0.6 || scale > 1.4) continue;
      if (std::isnan(best) || std::abs(scale - 1) < std::abs(best - 1)) best = scale;
    }
    if (!std::isnan(best)) scales.push_back(best);
  }
  if (scales.size() < 5) return std::nullopt;
  // The seed takes the mean of the per-point scales; outliers (a trace slipping to another edge)
  // are dropped first by their distance from the median.
  const double m = median(scales);
  std::vector<double> dev;
  for (double s : scales) dev.push_back(std::abs(s - m));
  const double mad = std::max(1e-4, 1.4826 * median(dev));
  double sum = 0, sum2 = 0;
  int n = 0;
  for (double s : scales)
    if (std::abs(s - m) <= 3 * mad) sum += s, sum2 += s * s, ++n;
  const double mean = sum / n, var = std::max(0.0, sum2 / n - mean * mean);
  return std::make_pair(mean, std::sqrt(var / n));
}

Panorama align_panorama(const std::vector<cv::Mat>& images, const PanoramaOptions& options,
                        const std::optional<PlaneContours>& contours) {
  std::vector<RulerAlignmentFrame> frames(images.size());
  bool any_ruler = false;
  tbb::parallel_for(0, int(images.size()), [&](int i) {
    images[size_t(i)].convertTo(frames[size_t(i)].image, CV_32F);
    frames[size_t(i)].mask = field_of_view_mask(frames[size_t(i)].image);
    frames[size_t(i)].ruler = find_ruler(frames[size_t(i)].image, frames[size_t(i)].mask);
  });
  for (const auto& f : frames) any_ruler = any_ruler || f.ruler.has_value();
  if (!any_ruler) throw_input_error("--images", "no ruler (a thread with graduations) found in any frame");
  const RulerAlignment a = align_on_ruler(frames, options.alignment);
  Panorama p;
  p.frames.resize(images.size());
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
      const Eigen::Vector2d t = rotation(-ri) * (a.frames[size_t(j)].translation_px - a.frames[size_t(i)].translation_px);
      const auto s = contour_plane_scale(contours->polylines[0], contours->polylines[1], rotation(rj - ri), centre, t);
      if (!s) {
        if (p.failure.empty())
          p.failure = "the contours do not cross the translation between their frames at enough points to fix the plane";
      } else {
        p.plane = "contours";
        p.plane_scale = s->first;
        p.plane_scale_sigma = s->second;
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
    const Eigen::Matrix2d R = rotation(a.frames[i].rotation_rad);
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

cv::Mat compose_panorama(const std::vector<cv::Mat>& images, const Panorama& p, PanoramaBlend blend) {
  struct Warped { cv::Rect roi; cv::Mat image, mask; };
  std::vector<Warped> warped;
  for (size_t i = 0; i < images.size(); ++i) {
    if (!p.frames[i].aligned) continue;
    cv::Mat img;
    images[i].convertTo(img, CV_32F);
    const cv::Mat mask = field_of_view_mask(img, 2);
    const Eigen::Matrix3d& H = p.frames[i].H_panorama_frame;
    Eigen::Vector2d lo(1e300, 1e300), hi(-1e300, -1e300);
    for (const auto& [u, v] : {std::pair{0, 0}, {img.cols - 1, 0}, {0, img.rows - 1}, {img.cols - 1, img.rows - 1}}) {
      const Eigen::Vector2d q = (H * Eigen::Vector3d(u, v, 1)).head<2>();
      lo = lo.cwiseMin(q), hi = hi.cwiseMax(q);
    }
    cv::Rect roi(int(std::floor(lo.x())), int(std::floor(lo.y())), 0, 0);
    roi.width = int(std::ceil(hi.x())) - roi.x + 1, roi.height = int(std::ceil(hi.y())) - roi.y + 1;
    roi &= cv::Rect(0, 0, p.width, p.height);
    cv::Mat m = (cv::Mat_<double>(2, 3) << H(0, 0), H(0, 1), H(0, 2) - roi.x, H(1, 0), H(1, 1), H(1, 2) - roi.y);
    Warped w;
    w.roi = roi;
    cv::warpAffine(img, w.image, m, roi.size(), cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(0));
    cv::warpAffine(mask, w.mask, m, roi.size(), cv::INTER_NEAREST, cv::BORDER_CONSTANT, cv::Scalar(0));
    warped.push_back(std::move(w));
  }
  cv::Mat out = cv::Mat::zeros(p.height, p.width, CV_32F);
  tbb::parallel_for(tbb::blocked_range<int>(0, p.height), [&](const tbb::blocked_range<int>& rows) {
    std::vector<float> values;
    for (int y = rows.begin(); y < rows.end(); ++y)
      for (int x = 0; x < p.width; ++x) {
        values.clear();
        for (const Warped& w : warped) {
          const int lx = x - w.roi.x, ly = y - w.roi.y;
          if (lx < 0 || ly < 0 || lx >= w.roi.width || ly >= w.roi.height || !w.mask.at<uint8_t>(ly, lx)) continue;
          values.push_back(w.image.at<float>(ly, lx));
        }
        if (values.empty()) continue;
        float v = values[0];
        switch (blend) {
          case PanoramaBlend::Max: v = *std::max_element(values.begin(), values.end()); break;
          case PanoramaBlend::Min: v = *std::min_element(values.begin(), values.end()); break;
          case PanoramaBlend::Mean: {
            double s = 0;
            for (float q : values) s += q;
            v = float(s / double(values.size()));
            break;
          }
          case PanoramaBlend::Median: {
            std::sort(values.begin(), values.end());
            const size_t h = values.size() / 2;
            v = values.size() % 2 ? values[h] : 0.5f * (values[h - 1] + values[h]);
            break;
          }
        }
        out.at<float>(y, x) = v;
      }
  });
  return out;
}

}  // namespace fluoro
