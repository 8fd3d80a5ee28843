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
    // Later rounds start from a smaller simplex: they polish rather than search.
    const SimplexResult r = minimize_simplex(f, Eigen::VectorXd::Zero(6), step / double(1 << round), options.simplex);
    start = apply_pose_parameters(r.x, start, c);
    result.score = -r.value * scale;
    result.evaluations += r.evaluations;
    result.iterations += r.iterations;
    result.converged = r.converged;
  }
  result.pose = start;
  return result;
}

}  // namespace fluoro
