#pragma once
// Nelder-Mead downhill simplex minimisation with batched evaluation. The initial and the shrunk
// simplexes are always scored in one batch. A step needs the reflection and then at most one
// more point (expansion or a contraction); `speculative` scores all four candidates in one batch
// instead: the same iterates, one batch per step but about twice the evaluations. That pays
// where a batch of four costs about as much as one (a GPU's dispatch latency), not on a CPU.
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
  bool speculative = false;
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
