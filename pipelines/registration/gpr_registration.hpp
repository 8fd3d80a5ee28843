#pragma once
// Fine gradient projection registration (seed, chapter 2, section VII): the pose of the CT that
// maximises the GPR score of the X-rays' edge pixels over the six pose parameters, by batched
// quasi-Newton steps (quasi_newton.hpp) or by downhill simplex (simplex.hpp), the points scored
// in batches on the backend.
#include <span>

#include "engine/backend.hpp"
#include "pipelines/registration/quasi_newton.hpp"
#include "pipelines/registration/simplex.hpp"

namespace fluoro {

// The simplex's pose parameters: x = (rotation vector in degrees, translation in mm) applied about
// the world position `centre_world` of the bone's centre: T(x) = Tr(c + t) R(r) Tr(-c) T0.
Pose apply_pose_parameters(const Eigen::VectorXd& x, const Pose& initial, const Eigen::Vector3d& centre_world);

// The fine step's optimiser. The simplex (the default) scores one or two poses per step;
// quasi_newton a 12-pose finite-difference stencil and a 3-pose line search per iteration, two
// backend batches (docs/registration.md, section 3, and docs/benchmarks.md measure both).
enum class FineOptimiser { simplex, quasi_newton };

struct GprRegistrationOptions {
  GprParams gpr;
  FineOptimiser optimiser = FineOptimiser::simplex;
  // The parameters' scale: the initial simplex, or the quasi-Newton's difference steps and trust
  // radius (as fractions and multiples of it): rotations about the bone's centre (degrees) and
  // translations (mm).
  double rotation_step_deg = 2.0;
  double translation_step_mm = 2.0;
  // Tolerances are in degrees and millimetres (x) and in units of the starting score (f).
  SimplexOptions simplex{300, 1e-5, 0.05};
  // The quasi-Newton's; its tolerances are the simplex's (f_tolerance, x_tolerance), and its
  // iterations at most max_iterations.
  QuasiNewtonOptions quasi_newton;
  // Restart from the optimum with a fresh simplex this many times: a collapsed simplex can stall
  // short of the optimum.
  int restarts = 1;
};

struct GprRegistrationResult {
  Pose pose;              // T_world_ct
  double score = 0;       // GPR score at pose
  double initial_score = 0;
  int evaluations = 0, iterations = 0;
  bool converged = false;  // the last optimiser run met its tolerances
};

// Refines T_world_ct from `initial`. `centre_ct` is the point (CT frame) rotations turn about,
// best the centre of the bone, which decouples rotation from translation.
GprRegistrationResult register_gpr(Backend& backend, const DeviceVolume& gradient, std::span<const PinholeCamera> views,
                                   std::span<const EdgePixels> edges, const Pose& initial,
                                   const Eigen::Vector3d& centre_ct, const GprRegistrationOptions& options = {});

}  // namespace fluoro
