#pragma once
// A DRR of the bone moved by a small translation, from the DRR before the move, without rendering.
//
// Under a pinhole camera, moving a plane parallel to the detector (at depth z, camera frame) by tau
// (camera frame) maps its image by an affine map: pixel v of the moved plane shows what pixel
// u = s v - (K tau)_xy / z showed before, with s = (z + tau_z) / z. A line integral through bone
// at depth z' moves by z / z' times as much (parallax), so taking the plane through the bone's
// centre is exact there and off by |z' - z| / z of that bone's own shift elsewhere: 0.05 to 0.25
// of a 3 mm shift (0.15 to 0.75 mm) for bone 30 to 150 mm in front of or behind the centre at the
// default C-arm's 600 mm from source to isocentre. The peak-sharpness check (peak_sharpness.hpp) compares the X-ray and the DRR at the
// result with the same moved image, so such an error changes what is tested (a displacement a
// little different from a rigid one) alike for both, not the comparison. Its translations come
// from here: half of its renders saved (measured in docs/benchmarks.md, "The six translations
// warped, not rendered"). So do the correlation polish's stencils' (correlation_polish.hpp), whose
// parabolas place the pose: the error is odd in the displacement (bone in front of the plane moves
// too little either way), so it scales each step (2 to 8 % shorter) but, to first order, not
// where the step is zero, the pose the polish converges to (measured: results within 0.01 mm of
// the rendered stencils', docs/benchmarks.md, "The polish's stencils warped too").
#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "engine/camera.hpp"

namespace fluoro {

// `drr` (CV_32F, camera's image size or a reduced one: `camera` must be the camera of that size)
// as it would be with the bone moved by `translation_world` (mm), for the plane through
// `centre_world`. Cubic interpolation; pixels mapped from outside the image repeat the border.
cv::Mat translated_drr(const cv::Mat& drr, const PinholeCamera& camera, const Eigen::Vector3d& centre_world,
                       const Eigen::Vector3d& translation_world);

}  // namespace fluoro
