#pragma once
// The last fine step: the pose that maximises the gradient correlation (Penney et al.) of the
// X-rays with bone DRRs, by parabola steps from the confidence check's own displaced poses.
//
// Why: the GPR score counts the X-ray's Canny edge pixels, and under imaging physics the DRR
// model lacks (scatter, detector blur) those pixels move and the score's optimum flattens into a
// plateau on which the GPR stops anywhere (pelvis CT, 10 mm starts, 1 px blur: 0.12 to
// 1.0 mm). The gradient correlation compares whole gradient profiles; on the same runs it ranked
// the results in the order of their true error (docs/registration.md, "Robustness to imaging
// physics").
//
// How: the peak-sharpness check (peak_sharpness.hpp) measures the GPR's pose and its 12
// displacements (+-3 degrees, +-3 mm) anyway (the six translations warped from the pose's DRR,
// translated_drr.hpp). Through each axis's three mean correlations a
// parabola peaks somewhere; the first step moves every axis there at once, times 4/3: at that
// scale the correlation is peaked more like |x| than like x^2, where a parabola through +-d finds
// about half the way (4/3 leaves a third of the error either way). Each step's pose is rendered
// with a stencil of +-1 degree and mm (the check's measurement at that scale: its translations
// warped like the check's, so 7 poses rendered, one batch), which gives the next step (a parabola
// at that scale is close to the peak; 4/3 there made the steps alternate in sign), and is taken
// only when it correlates better than the pose before; until a step would move no axis more than
// the tolerance, or the last allowed step, whose pose is rendered as the confidence check (its
// displacements, not a stencil's: no step follows). The check is measured at the result unless
// it already was. A 6-parameter diagonal step ignores couplings between the axes; the later
// steps take up what it leaves.
#include <functional>
#include <span>
#include <vector>

#include "engine/pose.hpp"
#include "pipelines/registration/peak_sharpness.hpp"

namespace fluoro {

// The peak-sharpness measurement of a pose (its correlations and its displacements') with the
// given displacements: the confidence check's, or a stencil's. It must displace about the point
// the steps turn about (`centre_ct` of polish_by_correlation, through the pose).
using MeasurePeak = std::function<PeakSharpness(const Pose&, const PeakSharpnessOptions&)>;

struct CorrelationPolishOptions {
  double first_relaxation = 4.0 / 3.0;  // the first step's, from the check's stencil (above)
  double displacement = 1.0;            // degrees and mm: the later steps' stencil
  double tolerance = 0.02;              // stop when no axis would move more (degrees or mm)
  int max_steps = 3;                    // steps, the first one's included (one measurement each)
};

struct CorrelationPolishResult {
  Pose pose;
  PeakSharpness at_pose;  // the measurement of `pose`: the result's confidence check
  double correlation = 0, initial_correlation = 0;  // mean over the views
  int evaluations = 0;  // poses rendered beyond the initial measurement
  int steps = 0;        // steps tried (each a stencil), the first one's included
  bool converged = false;
};

// Mean over the views of the correlation at the pose (index 0) and at each displaced pose (1 to
// 12, displaced_poses' order); empty when a view lacks its displaced correlations.
std::vector<double> mean_displaced_correlations(const PeakSharpness& p);

// From the correlations at a pose and at its 12 displacements (displaced_poses' order, +-rotation_deg
// and +-translation_mm): the step (apply_pose_parameters' parameters, degrees about the bone centre
// and mm) that puts each axis at the peak of the parabola through its three, times `relaxation`
// and at most half a displacement. An axis whose correlation does not drop moves half a
// displacement uphill (not at all when both sides are equal). Zero without 13 correlations.
Eigen::Matrix<double, 6, 1> parabola_peak_step(std::span<const double> correlations, double rotation_deg,
                                               double translation_mm, double relaxation);

// From `initial`, measured as `at_initial` (its own displacements set the first step's scale).
// Never returns a pose that correlates less than `initial`. `centre_ct`: the point the rotations
// turn about. The stencils are measured with at_initial's options at `displacement`.
CorrelationPolishResult polish_by_correlation(const MeasurePeak& measure, const Pose& initial, PeakSharpness at_initial,
                                              const Eigen::Vector3d& centre_ct, const CorrelationPolishOptions& options);

}  // namespace fluoro
