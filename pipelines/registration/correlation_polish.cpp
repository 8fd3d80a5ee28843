#include "pipelines/registration/correlation_polish.hpp"

#include <algorithm>

#include "pipelines/registration/gpr_registration.hpp"

namespace fluoro {

std::vector<double> mean_displaced_correlations(const PeakSharpness& p) {
  if (p.views.empty()) return {};
  std::vector<double> mean(13, 0.0);
  for (const ViewSharpness& v : p.views) {
    if (v.measured.size() != 12) return {};
    mean[0] += v.correlation;
    for (size_t k = 0; k < 12; ++k) mean[k + 1] += v.measured[k];
  }
  for (double& m : mean) m /= double(p.views.size());
  return mean;
}

Eigen::Matrix<double, 6, 1> parabola_peak_step(std::span<const double> c, double rotation_deg, double translation_mm,
                                               double relaxation) {
  Eigen::Matrix<double, 6, 1> x = Eigen::Matrix<double, 6, 1>::Zero();
  if (c.size() != 13) return x;
  for (int a = 0; a < 6; ++a) {
    const double d = a < 3 ? rotation_deg : translation_mm;
    const double minus = c[1 + 2 * a], plus = c[2 + 2 * a], drop = c[0] - 0.5 * (minus + plus);
    // f(x) = c + b x - k x^2 through (-d, minus), (0, c), (d, plus) peaks at d (plus - minus) / 4 drop.
    // No drop: no peak between the displacements; half a displacement towards the higher side.
    const double uphill = plus > minus ? d : plus < minus ? -d : 0.0;
    const double peak = drop > 0 ? relaxation * d * (plus - minus) / (4 * drop) : uphill;
    x[a] = std::clamp(peak, -0.5 * d, 0.5 * d);
  }
  return x;
}

CorrelationPolishResult polish_by_correlation(const MeasurePeak& measure, const Pose& initial, PeakSharpness at_initial,
                                              const Eigen::Vector3d& centre_ct, const CorrelationPolishOptions& o) {
  CorrelationPolishResult r;
  r.pose = initial;
  const std::vector<double> first = mean_displaced_correlations(at_initial);
  r.initial_correlation = r.correlation = first.empty() ? 0.0 : first[0];
  const PeakSharpnessOptions checked = at_initial.options;
  r.at_pose = std::move(at_initial);
  if (first.empty()) return r;
  Eigen::Matrix<double, 6, 1> step =
      parabola_peak_step(first, checked.rotation_deg, checked.translation_mm, o.first_relaxation);
  PeakSharpnessOptions small = checked;
  small.rotation_deg = small.translation_mm = o.displacement;
  bool measured = true;  // r.at_pose is of r.pose
  for (int k = 0; k < o.max_steps; ++k) {
    if (step.cwiseAbs().maxCoeff() < o.tolerance) {
      r.converged = true;
      break;
    }
    const Pose next = apply_pose_parameters(step, r.pose, r.pose * centre_ct);
    ++r.steps;
    if (k + 1 == o.max_steps) {
      // The last step: no step follows, so its pose needs only its correlation, which the
      // confidence check's measurement gives (and is then already the result's).
      PeakSharpness at_next = measure(next, checked);
      r.evaluations += at_next.evaluations;
      const std::vector<double> m = mean_displaced_correlations(at_next);
      const double c = m.empty() ? 0.0 : m[0];
      if (c > r.correlation) {
        r.pose = next;
        r.correlation = c;
        r.at_pose = std::move(at_next);
        measured = true;
      }
      break;
    }
    const PeakSharpness stencil = measure(next, small);
    r.evaluations += stencil.evaluations;
    const std::vector<double> c = mean_displaced_correlations(stencil);
    if (c.empty() || !(c[0] > r.correlation)) break;  // overshot, or noise: the pose before is the best seen
    r.pose = next;
    r.correlation = c[0];
    measured = false;
    step = parabola_peak_step(c, o.displacement, o.displacement, 1.0);
  }
  if (!measured) {
    r.at_pose = measure(r.pose, checked);
    r.evaluations += r.at_pose.evaluations;
  }
  return r;
}

}  // namespace fluoro
