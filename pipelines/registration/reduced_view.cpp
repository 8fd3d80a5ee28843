#include "pipelines/registration/reduced_view.hpp"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

#include "engine/error.hpp"
#include "engine/image_mat.hpp"
#include "pipelines/registration/triangulation.hpp"

namespace fluoro {

int size_reduction(const PinholeCamera& camera, int max_side) {
  return std::max(1, (std::max(camera.width, camera.height) + max_side - 1) / max_side);
}

ReducedView reduce_view_by(const PinholeCamera& camera, const Image& image, int factor) {
  ReducedView r;
  const int f = std::max(1, factor);
  r.factor = f;
  r.camera = camera;
  r.camera.width = camera.width / f;
  r.camera.height = camera.height / f;
  // Pixel (0, 0) of the reduced image is the centre of the top-left f x f block.
  Eigen::Matrix3d S = Eigen::Matrix3d::Identity();
  S(0, 0) = S(1, 1) = 1.0 / f;
  S(0, 2) = S(1, 2) = -0.5 + 0.5 / f;
  r.camera.K = S * camera.K;
  const cv::Mat full = mat_view(image);
  cv::resize(full(cv::Rect(0, 0, r.camera.width * f, r.camera.height * f)), r.image,
             cv::Size(r.camera.width, r.camera.height), 0, 0, cv::INTER_AREA);
  return r;
}

ReducedView reduce_view(const PinholeCamera& camera, const Image& image, int max_side) {
  return reduce_view_by(camera, image, size_reduction(camera, max_side));
}

std::vector<int> correlation_reductions(const std::vector<PinholeCamera>& cameras, double voxel_mm, int max_side,
                                        double min_pixels_per_voxel, int min_side) {
  std::vector<int> factors;
  for (const PinholeCamera& c : cameras) factors.push_back(size_reduction(c, max_side));
  std::vector<Eigen::Vector2d> principal_points;
  for (const PinholeCamera& c : cameras) principal_points.emplace_back(c.K(0, 2), c.K(1, 2));
  Eigen::Vector3d isocentre;
  try {
    isocentre = triangulate(cameras, principal_points, "the views' principal rays").point;
  } catch (const InputError&) {
    return factors;  // no isocentre: parallel views (or a single one)
  }
  for (size_t v = 0; v < cameras.size(); ++v) {
    const PinholeCamera& c = cameras[v];
    const double depth = (c.R * isocentre + c.t).z();
    // The coarser axis's pixel: both axes keep at least min_pixels_per_voxel.
    const double focal_px = std::min(std::abs(c.K(0, 0)), std::abs(c.K(1, 1)));
    if (!(depth > 0) || !(focal_px > 0) || !(voxel_mm > 0) || !(min_pixels_per_voxel > 0)) continue;  // the size rule
    const double pixel_at_isocentre_mm = depth / focal_px;  // a full-size pixel's footprint there
    const double by_voxel = std::floor(voxel_mm / (min_pixels_per_voxel * pixel_at_isocentre_mm));
    const int by_min_side = std::max(1, std::min(c.width, c.height) / std::max(1, min_side));
    factors[v] = std::max(factors[v], int(std::clamp(by_voxel, 1.0, double(by_min_side))));
  }
  return factors;
}

}  // namespace fluoro
