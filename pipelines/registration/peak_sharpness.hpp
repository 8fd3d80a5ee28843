#pragma once
// Failure detection that does not depend on an absolute correlation level: is the result, in every
// view, the sharp maximum of the gradient correlation that a right pose is on this CT?
//
// Near the bone's edges an X-ray is a scaled copy of the bone DRR plus content the bone DRR lacks
// (soft tissue, other anatomy, tools, scatter). When that content is uncorrelated with the bone's
// gradients, the X-ray's correlation with the DRR at a displaced pose, divided by its correlation
// at the result, equals the correlation of the DRR at the result with the DRR at the displaced
// pose. So around a right pose each view's *relative* drop is what the CT's own DRR predicts,
// whatever the absolute level (which soft tissue, beam hardening or scatter lower), and each view
// peaks where the others do. Two tests per view and displacement axis, both free of the level:
// - sharpness: the measured relative drop over the simulated one (about 1 at a right pose; a view
//   that a wrong pose fits by accidental overlap drops less);
// - peak offset: where a parabola through the view's correlations at -d, 0 and +d peaks (a right
//   pose is at every view's peak; a wrong one is a compromise that each view would leave in its
//   own direction).
// Every axis along which the view's simulated correlation drops measurably is judged on its
// sharpness (a view hardly sees a shift along its own ray, which is left out), but only the axes it
// sees strongly (drops at least half as much as along its most sensitive axis) on their peak offset.
// A weakly seen axis (a head's rotations about its centre, a femur's about its shaft) determines
// the pose weakly: the registration leaves a right pose up to a degree off there under imaging
// physics, so its peak offset says little, but a wrong pose's correlation hardly drops along it.
// Judging only the strong axes let a head pose 5 degrees off pass as confident: sharp on every
// translation, its views' correlations dropped a seventh to a third of the prediction about most of
// its weakly seen rotations (five displaced correlations rose above the result's).
//
// Displacements: +-rotation_deg about each axis through the bone centre, +-translation_mm along
// each axis (12 poses; the result and its rotations are one backend batch of bone DRRs at the
// gradient correlation's reduced size, its translations the DRR at the result moved in the image,
// translated_drr.hpp).
// The result itself is never moved: this only measures.
#include <vector>

#include "engine/pose.hpp"

namespace fluoro {

struct PeakSharpnessOptions {
  double rotation_deg = 3.0, translation_mm = 3.0;  // the displacements
  // A view's sharpness is judged on the axes whose simulated correlation drops (from 1) by at least
  // `min_judged_drop` or by `informative_axis_fraction` of its largest drop, its peak offset on the
  // second only.
  double min_judged_drop = 0.03;
  double informative_axis_fraction = 0.5;
  // Every judged axis of every view must reach this sharpness ...
  double min_axis_sharpness = 0.45;
  // ... and each strongly seen axis's parabola must peak within this many mm (translations) or
  // degrees (rotations).
  double max_peak_offset = 0.4;
  // The six translated DRRs of each view from the DRR at the result (translated_drr.hpp), the
  // rotated ones rendered: 7 renders a view instead of 13. false renders all 13.
  bool translations_by_warp = true;
};

// The 12 displaced poses (order: rotation about x by -d, +d, then y, z, then translation along x
// by -d, +d, then y, z), as the parameters of apply_pose_parameters about `centre_world`.
inline constexpr size_t kDisplacedRotations = 6;  // the first six, rendered; the translations may be warped
std::vector<Pose> displaced_poses(const Pose& pose, const Eigen::Vector3d& centre_world, const PeakSharpnessOptions& o);

struct ViewSharpness {
  double correlation = 0;            // X-ray with the bone DRR at the result
  double displaced_correlation = 0;  // ... at the displaced poses, mean
  double simulated_displaced = 0;    // the DRR at the result with the DRRs at the displaced poses, mean
  double sharpness = 0;              // the least sharpness of a judged axis
  double peak_offset = 0;            // the largest |peak offset| of a strongly seen axis (mm or degrees)
  int judged_axes = 0;               // on sharpness; of these, the strongly seen ones on peak offset
  std::vector<double> measured, simulated;  // per displaced pose (displaced_poses' order)
};

// One view's test from its correlations: `correlation` at the result, `measured` (with the X-ray)
// and `simulated` (with the DRR at the result) at the displaced poses. A view that does not
// correlate positively at the result gets sharpness 0 and an infinite offset; one whose correlation
// does not drop along a judged axis, a sharpness of 0 or less (at least -1), and along a strongly
// seen axis an infinite offset too.
ViewSharpness view_sharpness(double correlation, const std::vector<double>& measured, const std::vector<double>& simulated,
                             const PeakSharpnessOptions& o);

struct PeakSharpness {
  std::vector<ViewSharpness> views;
  double min_sharpness = 0;    // over the views
  double max_peak_offset = 0;  // over the views
  bool sharp = false;          // every view passes both tests
  PeakSharpnessOptions options;  // what it was measured with
  int evaluations = 0;           // poses rendered (the result and its rotations; and translations unless warped)
  double seconds = 0;
};

// The verdict over the views' tests.
PeakSharpness judge_peak_sharpness(std::vector<ViewSharpness> views, const PeakSharpnessOptions& o);

}  // namespace fluoro
