#include "pipelines/registration/correlation_polish.hpp"

#include "pipelines/registration/gpr_registration.hpp"

namespace fluoro {

CorrelationPolishResult polish_by_correlation(const PoseCorrelations& correlate, const Pose& initial,
                                              const Eigen::Vector3d& centre_ct, const CorrelationPolishOptions& o) {
  CorrelationPolishResult result;
  result.pose = initial;
  result.initial_correlation = result.correlation = correlate(std::span(&initial, 1))[0];
  const Eigen::Vector3d c = initial * centre_ct;
  const BatchObjective f = [&](const std::vector<Eigen::VectorXd>& xs) {
    std::vector<Pose> poses;
    poses.reserve(xs.size());
    for (const auto& x : xs) poses.push_back(apply_pose_parameters(x, initial, c));
    std::vector<double> out = correlate(poses);
    for (double& v : out) v = -v;
    return out;
  };
  Eigen::VectorXd step(6);
  step << Eigen::Vector3d::Constant(o.rotation_step_deg), Eigen::Vector3d::Constant(o.translation_step_mm);
  const SimplexResult r = minimize_simplex(f, Eigen::VectorXd::Zero(6), step, o.simplex);
  result.evaluations = r.evaluations + 1;
  result.iterations = r.iterations;
  result.converged = r.converged;
  if (-r.value > result.correlation) {
    result.pose = apply_pose_parameters(r.x, initial, c);
    result.correlation = -r.value;
  }
  return result;
}

}  // namespace fluoro
