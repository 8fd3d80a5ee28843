#include "pipelines/registration/translated_drr.hpp"

#include <opencv2/imgproc.hpp>

namespace fluoro {

cv::Mat translated_drr(const cv::Mat& drr, const PinholeCamera& camera, const Eigen::Vector3d& centre_world,
                       const Eigen::Vector3d& translation_world) {
  const double z = (camera.R * centre_world + camera.t).z();
  const Eigen::Vector3d tau = camera.R * translation_world;
  const Eigen::Vector3d k_tau = camera.K * tau;
  const double s = (z + tau.z()) / z;
  // For each output pixel v, the input pixel s v + b (warpAffine's inverse map).
  const cv::Matx23d map(s, 0, -k_tau.x() / z, 0, s, -k_tau.y() / z);
  cv::Mat out;
  cv::warpAffine(drr, out, map, drr.size(), cv::INTER_CUBIC | cv::WARP_INVERSE_MAP, cv::BORDER_REPLICATE);
  return out;
}

}  // namespace fluoro
