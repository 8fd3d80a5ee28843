#pragma once
// The orthopaedic ruler in one frame (seed ch. 3, Table I steps 1-2): its main thread, a pair of
// parallel lines found by a Hough transform, and its graduations found by 1D edges along it.
#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <optional>
#include <vector>

namespace fluoro {

// The thread's centre line: direction e = (cos a, sin a), normal n = (-sin a, cos a) pointing to
// the graduations' side; points u with n.(u - centre) = offset_px. `centre` is the image centre.
struct RulerThread {
  double angle_rad = 0;
  double offset_px = 0;
  double width_px = 0;
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();
  Eigen::Vector2d direction() const;
  Eigen::Vector2d normal() const;
};

// A ruler-aligned resampling of a frame: column x is along-coordinate a = x - half_length, row y
// is across-coordinate b = y + b_first (pixels from the thread's centre line, + towards the marks).
struct RulerStrip {
  cv::Mat image;  // CV_32F
  cv::Mat valid;  // CV_8U, 255 where the source pixel lies in the field of view
  int half_length = 0;
  int b_first = 0;
};

// One frame's ruler: thread, graduation centres along the thread (a, pixels from the foot of the
// image centre) with their lattice indices, and the frame's own lattice fit a = phase + k pitch.
struct RulerFrame {
  RulerThread thread;
  std::vector<double> mark_a;   // inlier graduation centres
  std::vector<long> mark_k;     // their lattice indices (frame-local numbering)
  int marks_found = 0;          // candidate marks before the lattice fit
  double pitch_px = 0, phase_px = 0, lattice_rms_px = 0;
  RulerStrip strip;             // thread and marks, for the sub-pixel NCC between frames
  // From the marks' lengths: the lattice index of a 10 mm mark modulo 2, and of a 50 mm mark
  // modulo 10 (-1 when not seen), which fix the graduation count between frames up to 50 mm.
  int medium_parity = -1, long_residue = -1;
};

// Finds the ruler in a frame (CV_32F, log domain: metal dark) within the field-of-view mask. The
// thread candidates are pairs of parallel Hough lines bounding a dark band; the one with the most
// graduations on a regular lattice wins. nullopt when no candidate shows at least 4 graduations.
std::optional<RulerFrame> find_ruler(const cv::Mat& image, const cv::Mat& fov_mask);

// Resamples the frame along a thread: along-coordinates [-half_length, half_length], across
// [b_first, b_last] (pixels), bilinear.
RulerStrip ruler_strip(const cv::Mat& image, const cv::Mat& fov_mask, const RulerThread& thread, int half_length,
                       int b_first, int b_last);

}  // namespace fluoro
