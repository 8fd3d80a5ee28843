#include "pipelines/registration/peak_sharpness.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include "pipelines/registration/gpr_registration.hpp"

namespace fluoro {
namespace {

double mean(const std::vector<double>& v) { return v.empty() ? 0.0 : std::accumulate(v.begin(), v.end(), 0.0) / double(v.size()); }

}  // namespace

std::vector<Pose> displaced_poses(const Pose& pose, const Eigen::Vector3d& centre_world, const PeakSharpnessOptions& o) {
  std::vector<Pose> out;
  for (int axis = 0; axis < 6; ++axis)
    for (double sign : {-1.0, 1.0}) {
      Eigen::VectorXd x = Eigen::VectorXd::Zero(6);
      x[axis] = sign * (axis < 3 ? o.rotation_deg : o.translation_mm);
      out.push_back(apply_pose_parameters(x, pose, centre_world));
    }
  return out;
}

ViewSharpness view_sharpness(double correlation, const std::vector<double>& measured, const std::vector<double>& simulated,
                             const PeakSharpnessOptions& o) {
  ViewSharpness s;
  s.correlation = correlation;
  s.displaced_correlation = mean(measured);
  s.simulated_displaced = mean(simulated);
  s.measured = measured;
  s.simulated = simulated;
  if (measured.size() != 12 || simulated.size() != 12 || !(correlation > 0)) {
    s.peak_offset = std::numeric_limits<double>::infinity();
    return s;
  }
  // Per axis: the drop of the mean of the two displaced correlations (the parabola's curvature).
  double simulated_drop[6], largest = 0;
  for (int a = 0; a < 6; ++a) {
    simulated_drop[a] = 1.0 - 0.5 * (simulated[2 * a] + simulated[2 * a + 1]);
    largest = std::max(largest, simulated_drop[a]);
  }
  // A pose whose displacements change nothing the view can see: nothing to judge, never sharp.
  if (!(largest > 1e-3)) {
    s.peak_offset = std::numeric_limits<double>::infinity();
    return s;
  }
  s.sharpness = std::numeric_limits<double>::infinity();
  const double strong = o.informative_axis_fraction * largest;
  int strong_axes = 0;
  for (int a = 0; a < 6; ++a) {
    if (simulated_drop[a] < strong && simulated_drop[a] < o.min_judged_drop) continue;
    ++s.judged_axes;
    const double minus = measured[2 * a], plus = measured[2 * a + 1];
    const double drop = correlation - 0.5 * (minus + plus);
    const double sharpness = drop / (correlation * simulated_drop[a]);
    s.sharpness = std::isnan(sharpness) ? -1.0 : std::min(s.sharpness, sharpness);  // NaN: never sharp
    if (simulated_drop[a] < strong) continue;  // a weakly seen axis: sharpness only (header)
    ++strong_axes;
    const double step = a < 3 ? o.rotation_deg : o.translation_mm;
    // f(x) = c + b x - k x^2 through (-1, minus), (0, c), (1, plus) peaks at b / 2k.
    const double offset = drop > 0 ? step * (plus - minus) / (4 * drop) : std::numeric_limits<double>::infinity();
    s.peak_offset = std::max(s.peak_offset, std::abs(offset));
  }
  if (s.judged_axes == 0) s.sharpness = 0;
  // No axis whose peak can be located (only with informative_axis_fraction over 1): no peak either.
  if (strong_axes == 0) s.peak_offset = std::numeric_limits<double>::infinity();
  s.sharpness = std::max(s.sharpness, -1.0);  // a rising correlation: as unsharp as can be, and finite
  return s;
}

PeakSharpness judge_peak_sharpness(std::vector<ViewSharpness> views, const PeakSharpnessOptions& o) {
  PeakSharpness p;
  p.options = o;
  p.views = std::move(views);
  p.min_sharpness = p.views.empty() ? 0.0 : std::numeric_limits<double>::infinity();
  for (const ViewSharpness& v : p.views) {
    p.min_sharpness = std::min(p.min_sharpness, v.sharpness);
    p.max_peak_offset = std::max(p.max_peak_offset, v.peak_offset);
  }
  p.sharp = !p.views.empty() && p.min_sharpness >= o.min_axis_sharpness && p.max_peak_offset <= o.max_peak_offset;
  return p;
}

}  // namespace fluoro
