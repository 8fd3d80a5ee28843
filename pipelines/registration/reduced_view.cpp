#include "pipelines/registration/reduced_view.hpp"

#include <algorithm>
#include <opencv2/imgproc.hpp>

#include "engine/image_mat.hpp"

namespace fluoro {

ReducedView reduce_view(const PinholeCamera& camera, const Image& image, int max_side) {
  ReducedView r;
  const int f = std::max(1, (std::max(camera.width, camera.height) + max_side - 1) / max_side);
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

}  // namespace fluoro
