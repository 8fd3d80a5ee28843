#pragma once
// The last fine step: the pose that maximises the gradient correlation (Penney et al.) of the
// X-rays with bone DRRs, by downhill simplex from the GPR's result.
//
// Why: the GPR score counts the X-ray's Canny edge pixels, and under imaging physics the DRR
// model lacks (scatter, detector blur) those pixels move and the score's optimum flattens into a
// plateau on which the polish stops anywhere (pelvis CT, 10 mm starts, 1 px blur: 0.12 to
// 1.0 mm). The gradient correlation compares whole gradient profiles; on the same runs it ranked
// the results in the order of their true error (docs/registration.md, "Robustness to imaging
// physics").
#include <functional>
#include <span>
#include <vector>

#include "engine/pose.hpp"
#include "pipelines/registration/simplex.hpp"

namespace fluoro {

// Mean gradient correlation over the views, per pose.
using PoseCorrelations = std::function<std::vector<double>(std::span<const Pose>)>;

struct CorrelationPolishOptions {
  double rotation_step_deg = 0.3, translation_step_mm = 0.3;  // the initial simplex
  SimplexOptions simplex{40, 2e-4, 0.03};                       // f: correlation units; x: deg and mm
};

struct CorrelationPolishResult {
  Pose pose;
  double correlation = 0, initial_correlation = 0;
  int evaluations = 0, iterations = 0;
  bool converged = false;
};

// Never returns a pose that correlates less than `initial`. `centre_ct`: the point rotations turn about.
CorrelationPolishResult polish_by_correlation(const PoseCorrelations& correlate, const Pose& initial,
                                              const Eigen::Vector3d& centre_ct, const CorrelationPolishOptions& options);

}  // namespace fluoro
