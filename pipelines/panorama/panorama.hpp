#pragma once
// Long-bone panorama (seed ch. 3, Table I): frames aligned on the ruler, optionally rescaled to the
// bone's plane from a contour traced on two consecutive frames (seed eqs. 8-10), composed on the
// first frame's axes. Frames come in already distortion-corrected (the dewarp is the caller's).
#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "pipelines/panorama/ruler_alignment.hpp"

namespace fluoro {

// The value of a panorama pixel that two or more frames cover (the seed found max the most
// uniform).
enum class PanoramaBlend { Max, Mean, Median, Min };

// The same anatomical contour on frames `first` and `first + 1`, in corrected pixels (C.json):
// it picks the plane the panorama is metric in.
struct PlaneContours {
  int first = 0;
  std::vector<Eigen::Vector2d> polylines[2];
};

// The method's settings: the ruler's graduation spacing, the blend, the alignment's thresholds.
struct PanoramaOptions {
  double graduation_mm = 5;
  PanoramaBlend blend = PanoramaBlend::Max;
  RulerAlignmentOptions alignment;
  // Largest relative standard error of the contours' plane scale, from their crossings
  // (plane_realignment.hpp) or the least-squares fit (contour_fit.hpp): a length error follows it
  // one for one.
  double max_plane_scale_sigma = 0.001;
};

// One frame's outcome. H maps a corrected frame pixel to panorama pixels (null when unaligned).
struct PanoramaFrame {
  bool aligned = false;
  double confidence = 0;
  std::optional<double> overlap;
  Eigen::Matrix3d H_panorama_frame = Eigen::Matrix3d::Identity();
  double rotation_deg = 0;
  Eigen::Vector2d translation_px = Eigen::Vector2d::Zero();
  int graduations = 0;
  std::string problem;
  // The ruler as found, in corrected frame pixels (for the overlay): the thread's ends inside the
  // field of view, its unit normal towards the graduations and its width, the graduations' feet on it.
  std::vector<Eigen::Vector2d> thread_px, graduations_px;
  Eigen::Vector2d thread_normal = Eigen::Vector2d::Zero();
  double thread_width_px = 0;
};

// The alignment's outcome: the panorama's size and scale in the chosen plane, one entry per frame,
// the uncertainty terms `fluoro measure` uses, and why frames could not be aligned.
struct Panorama {
  int width = 0, height = 0;
  double mm_per_pixel = 0;
  std::string plane = "ruler";         // "ruler" or "contours"
  double plane_scale = 1;              // translations' scale from the ruler's plane to the chosen one
  double plane_scale_sigma = 0;
  double ruler_mm_per_pixel = 0;
  double alignment_rms_px = 0;         // graduation / NCC residual of the adjustment
  double position_sigma_px = 0;        // largest standard error of a frame's position
  double scale_relative_sigma = 0;     // relative standard error of mm_per_pixel
  std::vector<PanoramaFrame> frames;
  std::string failure;                 // empty when every frame is aligned
  // Each frame's field of view eroded 2 px (CV_8U, 255 inside), found once during the alignment
  // so that compose_panorama need not find it again.
  std::vector<cv::Mat> field_masks;
};

// Finds the ruler in every frame and aligns them; with contours, rescales to their plane.
// InputError when no frame shows a ruler. The image is not composed (see compose_panorama).
Panorama align_panorama(const std::vector<cv::Mat>& frames, const PanoramaOptions& options,
                        const std::optional<PlaneContours>& contours);

// Warps the aligned frames into the panorama (cv::warpAffine) and blends overlapping pixels.
cv::Mat compose_panorama(const std::vector<cv::Mat>& frames, const Panorama& panorama, PanoramaBlend blend);

}  // namespace fluoro
