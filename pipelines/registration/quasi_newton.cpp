#include "pipelines/registration/quasi_newton.hpp"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>

namespace fluoro {
namespace {

// The line search's step lengths along the quasi-Newton direction: short, full and long, so that
// one batch covers an over- and an undershooting model.
constexpr double kLineSteps[] = {0.5, 1.0, 2.0};

}  // namespace

QuasiNewtonResult minimize_quasi_newton(const BatchObjective& f, const Eigen::VectorXd& x0, const Eigen::VectorXd& step,
                                        const QuasiNewtonOptions& o) {
  // Work in units of `step`, so that degrees and millimetres (or any mix) weigh alike.
  const int n = int(x0.size());
  const auto to_x = [&](const Eigen::VectorXd& z) -> Eigen::VectorXd { return x0 + z.cwiseProduct(step); };
  double x_tol = o.x_tolerance / step.cwiseAbs().maxCoeff();  // in step units: the finest axis decides
  for (int i = 0; i < n; ++i) x_tol = std::min(x_tol, o.x_tolerance / std::abs(step[i]));

  QuasiNewtonResult r;
  Eigen::VectorXd z = Eigen::VectorXd::Zero(n), g(n), z_prev, g_prev;
  Eigen::MatrixXd B;
  double fz = 0, h = o.difference_fraction, trust = o.initial_trust;
  bool have_value = false, reset = true;
  for (r.iterations = 0; r.iterations < o.max_iterations; ++r.iterations) {
    // The stencil (and, the first time, the centre).
    std::vector<Eigen::VectorXd> pts;
    for (int i = 0; i < n; ++i)
      for (const double sign : {1.0, -1.0}) {
        Eigen::VectorXd p = z;
        p[i] += sign * h;
        pts.push_back(to_x(p));
      }
    if (!have_value) pts.push_back(to_x(z));
    const std::vector<double> v = f(pts);
    r.evaluations += int(pts.size());
    ++r.batches;
    if (!have_value) {
      fz = v.back();
      have_value = true;
    }
    Eigen::VectorXd diag(n);
    double best = fz;
    Eigen::VectorXd best_z = z;
    for (int i = 0; i < n; ++i) {
      const double fp = v[size_t(2 * i)], fm = v[size_t(2 * i + 1)];
      g[i] = (fp - fm) / (2 * h);
      diag[i] = (fp + fm - 2 * fz) / (h * h);
      for (const auto& [value, sign] : {std::pair{fp, 1.0}, std::pair{fm, -1.0}})
        if (value < best) {
          best = value;
          best_z = z;
          best_z[i] += sign * h;
        }
    }
    // The Hessian model: BFGS from the last accepted step, or (first, after a failure, or when the
    // update would lose positive definiteness) the stencil's diagonal, floored so that no
    // coordinate's Newton step exceeds the trust radius.
    if (!reset && z_prev.size() == n) {
      const Eigen::VectorXd s = z - z_prev, y = g - g_prev;
      const double sy = s.dot(y);
      const Eigen::VectorXd Bs = B * s;
      const double sBs = s.dot(Bs);
      if (sy > 1e-12 * s.norm() * y.norm() && sBs > 0) B += y * y.transpose() / sy - Bs * Bs.transpose() / sBs;
      else reset = true;
    }
    Eigen::VectorXd p;
    for (int attempt = 0; attempt < 2; ++attempt) {
      if (reset) {
        B = Eigen::MatrixXd::Zero(n, n);
        for (int i = 0; i < n; ++i) B(i, i) = std::max(diag[i], std::abs(g[i]) / trust + 1e-12);
        reset = false;
      }
      const Eigen::LDLT<Eigen::MatrixXd> ldlt(B);
      p = -ldlt.solve(g);
      if (ldlt.info() == Eigen::Success && ldlt.isPositive() && p.allFinite() && p.dot(g) < 0) break;
      reset = true;
    }
    // The model's optimum is within the tolerances: done after scoring that optimum alone (the
    // last correction, finer than the tolerances; kept only if it scores better, as is a stencil
    // point that did).
    const double longest = p.cwiseAbs().maxCoeff();
    if (longest <= x_tol && -0.5 * g.dot(p) <= o.f_tolerance) {
      const double v_newton = f({to_x(z + p)})[0];
      ++r.evaluations;
      ++r.batches;
      if (v_newton < best) {
        best = v_newton;
        best_z = z + p;
      }
      z = best_z;
      fz = best;
      r.converged = true;
      ++r.iterations;
      break;
    }
    if (longest > trust) p *= trust / longest;
    // The line search, one batch.
    pts.clear();
    for (const double t : kLineSteps) pts.push_back(to_x(z + t * p));
    const std::vector<double> lv = f(pts);
    r.evaluations += int(pts.size());
    ++r.batches;
    int best_line = -1;
    for (size_t k = 0; k < lv.size(); ++k)
      if (lv[k] < best) {
        best = lv[k];
        best_z = z + kLineSteps[k] * p;
        best_line = int(k);
      }
    if (best < fz) {
      const double moved = (best_z - z).cwiseAbs().maxCoeff(), gained = fz - best;
      z_prev = z;
      g_prev = g;
      z = best_z;
      fz = best;
      // The model predicted well: trust it further; a short or a stencil step: less far.
      if (best_line == int(std::size(kLineSteps)) - 1) trust = std::min(2 * trust, o.max_trust);
      else if (best_line <= 0) trust = std::max(trust / 2, h);
      if (best_line < 0) reset = true;  // a stencil point: the gradient step did not pay
      if (gained <= o.f_tolerance && moved <= x_tol) {
        r.converged = true;
        ++r.iterations;
        break;
      }
    } else {
      // Nothing better within h or along the direction: the optimum is closer than h (or the
      // objective is rough at this scale). Look closer.
      if (h <= x_tol) {
        r.converged = true;
        ++r.iterations;
        break;
      }
      h = std::max(h / 2, x_tol);
      trust = std::max(trust / 2, h);
      reset = true;
    }
  }
  r.x = to_x(z);
  r.value = fz;
  return r;
}

}  // namespace fluoro
