#pragma once
// Quasi-Newton minimisation with batched finite differences, for objectives that are cheaper per
// point when scored in batches (the GPR score: one backend call for many poses) and smooth at the
// scale of the difference step. Each iteration scores two batches: the central-difference stencil
// about the current point (2n points: the gradient and the Hessian's diagonal) and a line search
// along the quasi-Newton direction (a few step lengths at once). The Hessian model starts from the
// stencil's diagonal and learns the couplings by BFGS updates; it is rebuilt from the diagonal when
// an iteration fails to descend. Any stencil or line point better than the current one is taken,
// so the method never moves uphill and, where the objective is rough, degrades to a pattern search.
// It stops when the model's own optimum is within the tolerances (no line search then), when an
// iteration gains less than f_tolerance and moves less than x_tolerance, or when nothing better
// is found within a difference step already at x_tolerance.
#include <Eigen/Core>

#include "pipelines/registration/simplex.hpp"

namespace fluoro {

struct QuasiNewtonOptions {
  int max_iterations = 20;
  // Stop when an iteration improves the value by less than f_tolerance (absolute) and moves every
  // parameter by less than x_tolerance (parameter units).
  double f_tolerance = 1e-4;
  double x_tolerance = 0.05;
  // The difference step, as a fraction of the scale `step` given to the minimiser; halved (down to
  // x_tolerance) when an iteration finds no better point.
  double difference_fraction = 0.25;
  // Trust radius: a step's largest parameter, in units of `step`.
  // The line search tries 0.5, 1 and 2 times the (clipped) step, so a point moves by at most
  // 2 x max_trust: the fine stages' initial simplex size at most, as the simplex's first steps.
  double initial_trust = 0.5, max_trust = 1.0;
};

struct QuasiNewtonResult {
  Eigen::VectorXd x;
  double value = 0;
  int iterations = 0;
  int evaluations = 0;
  int batches = 0;
  bool converged = false;
};

// Minimises f from x0. `step` is the parameters' scale (e.g. the initial simplex's step): the
// difference steps and the trust radius are fractions and multiples of it.
QuasiNewtonResult minimize_quasi_newton(const BatchObjective& f, const Eigen::VectorXd& x0, const Eigen::VectorXd& step,
                                        const QuasiNewtonOptions& options = {});

}  // namespace fluoro
