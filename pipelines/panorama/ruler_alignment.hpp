#pragma once
// Alignment of the frames on the ruler's plane (seed ch. 3, Table I step 3): the rotation and the
// across-ruler translation from the threads, the along-ruler translation chosen among the
// graduation-aligned candidates by NCC of the overlap, refined by cv::matchTemplate on the ruler,
// then one least-squares adjustment of all frames and all graduations together.
#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "pipelines/panorama/ruler.hpp"

namespace fluoro {

// One frame as the alignment sees it: the (already distortion-corrected) image, its field of
// view, and its ruler when one was found.
struct RulerAlignmentFrame {
  cv::Mat image;  // CV_32F
  cv::Mat mask;   // CV_8U field of view
  std::optional<RulerFrame> ruler;
};

struct RulerAlignmentOptions {
  double min_overlap = 0.10;  // least fraction of a frame shared with its predecessor
  double min_ncc = 0.65;      // least NCC of the overlap (anatomy, band-passed) for an accepted translation
  double min_margin = 0.10;   // least score lead over a count 10 mm away when no 50 mm mark fixes the count
  double max_pitch_deviation = 0.02;  // largest relative difference of a frame's graduation pitch from the median
  // Least share of a frame that its placement puts over an aligned frame other than the one it was
  // aligned to for that frame's image to be required to agree (NCC >= min_ncc) there too. Below
  // it the NCC cannot tell: correct placements scored down to 0.51 over 10-14 % shares.
  double min_check_overlap = 0.20;
};

// Where a frame goes, on the ruler's plane: panorama(u) = c + R(rotation)(u - c) + translation,
// c the image centre, panorama axes those of frame 0 (before any offset).
struct RulerPlacement {
  bool aligned = false;
  int predecessor = -1;            // the frame it was aligned to (-1: the reference)
  double rotation_rad = 0;
  Eigen::Vector2d translation_px = Eigen::Vector2d::Zero();
  double along_sigma_px = 0;       // standard error of its along-ruler position
  double ncc = 0, overlap = 0, confidence = 0;
  double refinement_px = 0;        // matchTemplate shift minus the graduation lattice's shift
  std::string problem;             // why it is not aligned
};

struct RulerAlignment {
  std::vector<RulerPlacement> frames;
  double pitch_px = 0;             // graduation pitch on the ruler's plane, all frames together
  double pitch_sigma_px = 0;
  double residual_rms_px = 0;      // graduations and NCC shifts after the adjustment
  int graduations_used = 0;
};

// Aligns frames (acquisition order) to frame 0. Frames whose ruler is missing, or whose overlap
// with an aligned predecessor (the previous frame, else the one before) is too small or does not
// correlate, are left unaligned with the reason.
RulerAlignment align_on_ruler(const std::vector<RulerAlignmentFrame>& frames, const RulerAlignmentOptions& options);

}  // namespace fluoro
