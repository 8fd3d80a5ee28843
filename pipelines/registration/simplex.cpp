#include "pipelines/registration/simplex.hpp"

#include <algorithm>
#include <numeric>

namespace fluoro {

SimplexResult minimize_simplex(const BatchObjective& f, const Eigen::VectorXd& x0, const Eigen::VectorXd& step,
                               const SimplexOptions& options) {
  const int n = int(x0.size());
  std::vector<Eigen::VectorXd> pts(size_t(n) + 1, x0);
  for (int i = 0; i < n; ++i) pts[size_t(i) + 1][i] += step[i];
  std::vector<double> val = f(pts);
  SimplexResult r;
  r.evaluations = n + 1;
  std::vector<size_t> order(size_t(n) + 1);
  for (r.iterations = 0; r.iterations < options.max_iterations; ++r.iterations) {
    std::iota(order.begin(), order.end(), size_t(0));
    std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return val[a] < val[b]; });
    const size_t best = order.front(), worst = order.back(), second = order[order.size() - 2];
    double spread = 0;
    for (const auto& p : pts) spread = std::max(spread, (p - pts[best]).cwiseAbs().maxCoeff());
    if (val[worst] - val[best] <= options.f_tolerance && spread <= options.x_tolerance) {
      r.converged = true;
      break;
    }
    Eigen::VectorXd centroid = Eigen::VectorXd::Zero(n);
    for (size_t i = 0; i < pts.size(); ++i)
      if (i != worst) centroid += pts[i];
    centroid /= n;
    const Eigen::VectorXd d = centroid - pts[worst];
    // Reflection, expansion, outside and inside contraction: the reflection decides which of the
    // others is needed.
    const std::vector<Eigen::VectorXd> trial = {centroid + d, centroid + 2 * d, centroid + 0.5 * d, centroid - 0.5 * d};
    std::vector<double> tv(4, 0.0);
    if (options.speculative) {
      tv = f(trial);
      r.evaluations += 4;
    } else {
      tv[0] = f({trial[0]})[0];
      const size_t next = tv[0] < val[best] ? 1 : tv[0] < val[second] ? 0 : tv[0] < val[worst] ? 2 : 3;
      if (next != 0) tv[next] = f({trial[next]})[0];
      r.evaluations += next != 0 ? 2 : 1;
    }
    const double fr = tv[0], fe = tv[1], foc = tv[2], fic = tv[3];
    if (fr < val[best]) {
      const bool expand = fe < fr;
      pts[worst] = expand ? trial[1] : trial[0];
      val[worst] = expand ? fe : fr;
    } else if (fr < val[second]) {
      pts[worst] = trial[0];
      val[worst] = fr;
    } else if (fr < val[worst] && foc <= fr) {
      pts[worst] = trial[2];
      val[worst] = foc;
    } else if (fr >= val[worst] && fic < val[worst]) {
      pts[worst] = trial[3];
      val[worst] = fic;
    } else {
      // Shrink towards the best vertex.
      std::vector<Eigen::VectorXd> shrunk;
      std::vector<size_t> index;
      for (size_t i = 0; i < pts.size(); ++i)
        if (i != best) {
          shrunk.push_back(pts[best] + 0.5 * (pts[i] - pts[best]));
          index.push_back(i);
        }
      const std::vector<double> sv = f(shrunk);
      r.evaluations += int(shrunk.size());
      for (size_t k = 0; k < index.size(); ++k) {
        pts[index[k]] = shrunk[k];
        val[index[k]] = sv[k];
      }
    }
  }
  const size_t best = size_t(std::min_element(val.begin(), val.end()) - val.begin());
  r.x = pts[best];
  r.value = val[best];
  return r;
}

}  // namespace fluoro
