#pragma once
// The nail's pose in the camera frame from its detection, both of the seed's modes.
// - Interactive (fronto-parallel): depth z = f d_world / d_image from the holes' diameters, the
//   long axis through the two hole centres, the hole axes along the viewing direction.
// - Generic (one image, any view): the pose that best predicts the image of the nail near its holes,
//   the exact chord of every pixel's ray through a metal cylinder with cylindrical holes (the hole's
//   lens shrinks as the view tilts: that is what fixes the tilt), fitted by Levenberg-Marquardt with
//   a smooth background per hole window and one common contrast solved in closed form at every step.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <string>
#include <vector>

#include "engine/distal_locking_models.hpp"
#include "engine/image.hpp"
#include "pipelines/calibration/dark_circle_detector.hpp"
#include "pipelines/distal_locking/nail_detection.hpp"
#include "pipelines/distal_locking/pose_refinement.hpp"

namespace fluoro {

// The nail has symmetries (a turn of 180 degrees about its y axis swaps equal holes; one about its
// x axis reverses the hole axes): among the poses they give, the one whose x and z axes are nearest
// the guide's x and z (in the camera frame) is reported, as the seed does.
struct NailPoseEstimate {
  bool ok = false;
  std::string failure_reason;
  CameraPose T_camera_nail = CameraPose::Identity();
  double rms = 0;             // image units, generic mode's fit
  double mirror_rms = 0;      // the fit from the best's mirror image (the single-image ambiguity)
  // The largest angle (degrees) between the reported hole axes and those of another fit the image
  // cannot tell from it (a tie the guide decided); 0 when no other fit ties.
  double tie_spread_deg = 0;
  int evaluations = 0;
  double attenuation_per_mm = 0;  // the nail's, fitted (line-integral units per mm)
  double blur_px = 0;          // the fitted blur (Gaussian sigma of the line integrals)
};

// The seed's interactive-mode pose (exact in a fronto-parallel view): the detected holes' centres
// at their depth, the hole axes along the ray. The depth is the seed's z = f d_world / d_image from
// the holes' mean outline diameter unless `hole_depths_mm` (camera z of each detected hole's centre,
// in the detection's order along the band) gives it: the outline at half contrast in the log domain
// lies outside the blurred hole's edge, which biases the seed's depth by 25-40 mm.
NailPoseEstimate fronto_parallel_nail_pose(const NailDetection& detection, const NailModel& nail, const Eigen::Matrix3d& K,
                                           const Eigen::Vector3d& guide_x, const Eigen::Vector3d& guide_z,
                                           const std::vector<double>& hole_depths_mm = {});

// Generic mode: the model fit from the best of `starts` (the first sets the windows);
// `occluders`: dark circles whose pixels are left out.
NailPoseEstimate fit_nail_pose(const Image& xray, const NailModel& nail, const Eigen::Matrix3d& K,
                               const std::vector<CameraPose>& starts, double band_width_px,
                               const std::vector<DarkCircle>& occluders, const Eigen::Vector3d& guide_x,
                               const Eigen::Vector3d& guide_z);

// Of the nail's symmetric poses, the one whose axes are nearest the guide's.
CameraPose nearest_symmetric_pose(const CameraPose& pose, const NailModel& nail, const Eigen::Vector3d& guide_x,
                                  const Eigen::Vector3d& guide_z);

}  // namespace fluoro
