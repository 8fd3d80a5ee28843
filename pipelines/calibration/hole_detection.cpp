// Holes are bright on the plate. A grey opening with a window much wider than a hole but narrower
// than the image's slow shading estimates the plate level; the top-hat (image - opening) leaves the
// holes (and bright dust) on a flat zero, whatever the exposure, heel effect or occluder edges.
#include "pipelines/calibration/hole_detection.hpp"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

#include "engine/field_of_view.hpp"
#include "engine/image_mat.hpp"

namespace fluoro {
namespace {

// Intensity-weighted centroid of the top-hat over a disc, re-centred a few times so the window is
// symmetric about the hole (a window fixed on the first guess would pull the centre towards it).
HoleBlob refine_centroid(const cv::Mat& tophat, Eigen::Vector2d c, double radius, double floor_level) {
  HoleBlob b;
  for (int it = 0; it < 4; ++it) {
    double sw = 0, su = 0, sv = 0;
    const int u0 = std::max(0, int(std::floor(c.x() - radius))), u1 = std::min(tophat.cols - 1, int(std::ceil(c.x() + radius)));
    const int v0 = std::max(0, int(std::floor(c.y() - radius))), v1 = std::min(tophat.rows - 1, int(std::ceil(c.y() + radius)));
    for (int v = v0; v <= v1; ++v)
      for (int u = u0; u <= u1; ++u) {
        if ((u - c.x()) * (u - c.x()) + (v - c.y()) * (v - c.y()) > radius * radius) continue;
        const double w = std::max(0.0, double(tophat.at<float>(v, u)) - floor_level);
        sw += w, su += w * u, sv += w * v;
      }
    if (!(sw > 0)) break;
    const Eigen::Vector2d next(su / sw, sv / sw);
    b.mass = sw;
    const bool settled = (next - c).norm() < 1e-4;
    c = next;
    if (settled) break;
  }
  b.centre_px = c;
  return b;
}

}  // namespace

HoleDetection detect_holes(const Image& image) {
  HoleDetection out;
  cv::Mat f = mat_view(image);
  const int side = std::min(image.width, image.height);
  if (side < 16) return out;

  // The field of view: the intensifier leaves everything outside its circle black.
  const cv::Mat lit = field_of_view_mask(f);
  out.illuminated_area_px = cv::countNonZero(lit);
  if (out.illuminated_area_px == 0) return out;

  const int k = std::max(15, (side / 20) | 1);
  cv::Mat opened, tophat;
  cv::morphologyEx(f, opened, cv::MORPH_OPEN, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(k, k)));
  tophat = f - opened;

  std::vector<float> lit_values;
  lit_values.reserve(size_t(out.illuminated_area_px));
  for (int v = 0; v < f.rows; ++v)
    for (int u = 0; u < f.cols; ++u)
      if (lit.at<uint8_t>(v, u)) lit_values.push_back(tophat.at<float>(v, u));
  if (lit_values.size() < 64) return out;
  const double median = percentile(lit_values, 0.5);
  std::vector<float> dev(lit_values.size());
  for (size_t i = 0; i < dev.size(); ++i) dev[i] = std::abs(lit_values[i] - float(median));
  const double sigma = 1.4826 * percentile(dev, 0.5);
  const double high = percentile(lit_values, 0.99);
  const double threshold = median + std::max(5 * sigma, 0.4 * (high - median));
  if (!(high - median > 5 * sigma)) return out;  // nothing stands out of the noise: no holes

  cv::Mat binary = (tophat > threshold) & lit, labels, stats, centroids;
  const int n = cv::connectedComponentsWithStats(binary, labels, stats, centroids, 8, CV_32S);
  std::vector<int> candidates;
  std::vector<double> areas;
  for (int i = 1; i < n; ++i)
    if (stats.at<int>(i, cv::CC_STAT_AREA) >= 3) candidates.push_back(i), areas.push_back(stats.at<int>(i, cv::CC_STAT_AREA));
  if (candidates.empty()) return out;
  std::vector<double> sorted = areas;
  std::nth_element(sorted.begin(), sorted.begin() + std::ptrdiff_t(sorted.size() / 2), sorted.end());
  const double typical_area = sorted[sorted.size() / 2];
  out.typical_diameter_px = 2 * std::sqrt(typical_area / 3.14159265358979);
  // The window reaches past the blurred, partial-volume rim but not to the next hole.
  const double window = 0.65 * out.typical_diameter_px + 2.0;
  for (size_t c = 0; c < candidates.size(); ++c) {
    const int i = candidates[c];
    const int w = stats.at<int>(i, cv::CC_STAT_WIDTH), h = stats.at<int>(i, cv::CC_STAT_HEIGHT);
    const double area = areas[c];
    if (area < 0.35 * typical_area || area > 3.0 * typical_area) continue;  // dust, merged or cut blobs
    if (std::max(w, h) > 2.5 * std::min(w, h) || area < 0.4 * w * h) continue;  // not round: edges, slivers
    HoleBlob b = refine_centroid(tophat, {centroids.at<double>(i, 0), centroids.at<double>(i, 1)}, window, median);
    b.area_px = area;
    out.blobs.push_back(b);
  }
  return out;
}

}  // namespace fluoro
