#include "pipelines/registration/gpr_registration.hpp"

#include <numbers>

namespace fluoro {
Pose apply_pose_parameters(const Eigen::VectorXd& x, const Pose& initial, const Eigen::Vector3d& c) {
  const Eigen::Vector3d r = x.head<3>() * (std::numbers::pi / 180.0);
  Pose delta = pose_from_rotation_vector(r, Eigen::Vector3d::Zero());
  delta.translation() = c + x.tail<3>() - delta.linear() * c;
  return delta * initial;
}

GprRegistrationResult register_gpr(Backend& backend, const DeviceVolume& gradient, std::span<const PinholeCamera> views,
                                   std::span<const EdgePixels> edges, const Pose& initial,
                                   const Eigen::Vector3d& centre_ct, const GprRegistrationOptions& options) {
  GprRegistrationResult result;
  Pose start = initial;
  result.initial_score = backend.gpr_score(gradient, std::span(&initial, 1), views, edges, options.gpr)[0];
  // Scores are normalised by the starting one so the tolerances do not depend on image content.
  const double scale = result.initial_score > 0 ? result.initial_score : 1.0;
  Eigen::VectorXd step(6);
  step << Eigen::Vector3d::Constant(options.rotation_step_deg), Eigen::Vector3d::Constant(options.translation_step_mm);
  for (int round = 0; round <= options.restarts; ++round) {
    const Eigen::Vector3d c = start * centre_ct;
    const BatchObjective f = [&](const std::vector<Eigen::VectorXd>& xs) {
      std::vector<Pose> poses;
      poses.reserve(xs.size());
      for (const auto& x : xs) poses.push_back(apply_pose_parameters(x, start, c));
      const std::vector<double> s = backend.gpr_score(gradient, poses, views, edges, options.gpr);
      std::vector<double> out(s.size());
      for (size_t i = 0; i < s.size(); ++i) out[i] = -s[i] / scale;
      return out;
    };
    // Later rounds start from a smaller scale: they polish rather than search.
    const Eigen::VectorXd round_step = step / double(1 << round);
    Eigen::VectorXd x;
    double value = 0;
    // Both optimisers report the same fields.
    const auto take = [&](const auto& r) {
      x = r.x;
      value = r.value;
      result.evaluations += r.evaluations;
      result.iterations += r.iterations;
      result.converged = r.converged;
    };
    if (options.optimiser == FineOptimiser::quasi_newton) {
      QuasiNewtonOptions q = options.quasi_newton;
      q.f_tolerance = options.simplex.f_tolerance;
      q.x_tolerance = options.simplex.x_tolerance;
      take(minimize_quasi_newton(f, Eigen::VectorXd::Zero(6), round_step, q));
    } else {
      take(minimize_simplex(f, Eigen::VectorXd::Zero(6), round_step, options.simplex));
    }
    start = apply_pose_parameters(x, start, c);
    result.score = -value * scale;
  }
  result.pose = start;
  return result;
}

}  // namespace fluoro
