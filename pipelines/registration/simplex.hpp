#pragma once
// Nelder-Mead downhill simplex minimisation with batched evaluation: every point the method may
// need next (reflection, expansion and both contractions; or the shrunk simplex) is evaluated in
// one call, so a backend scores them in one batch. It costs a few extra evaluations per step
// but turns each step into a single batch.
#include <Eigen/Core>
#include <functional>
#include <vector>

namespace fluoro {

// Values of the objective at each point, in order.
using BatchObjective = std::function<std::vector<double>(const std::vector<Eigen::VectorXd>&)>;

struct SimplexOptions {
  int max_iterations = 400;
  // Stop when the simplex's values differ by less than this (absolute) and its vertices by less
  // than x_tolerance (in parameter units) from the best one.
  double f_tolerance = 1e-6;
  double x_tolerance = 1e-3;
};

struct SimplexResult {
  Eigen::VectorXd x;
  double value = 0;
  int iterations = 0;
  int evaluations = 0;
  bool converged = false;
};

// Minimises f from x0 with an initial simplex of x0 and x0 + step_i e_i.
SimplexResult minimize_simplex(const BatchObjective& f, const Eigen::VectorXd& x0, const Eigen::VectorXd& step,
                               const SimplexOptions& options = {});

}  // namespace fluoro
