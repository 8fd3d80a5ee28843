#pragma once
// The sampled Gaussian and Gaussian-derivative filters used by every backend's gradient field, so
// that they all compute the same field. Correlation form: out(x) = sum_i w[i + r] * f(x + i).
#include <cmath>
#include <vector>

namespace fluoro {

struct DerivativeFilter {
  int radius = 0;
  std::vector<double> smooth;      // sums to 1
  std::vector<double> derivative;  // sum_i i * derivative[i + r] = 1: exact on linear ramps
};

// sigma in voxels along one axis. The radius covers 4 sigma (at least one voxel), so a tiny sigma
// degrades gracefully to central differences.
inline DerivativeFilter make_derivative_filter(double sigma_voxels) {
  DerivativeFilter f;
  const double s = sigma_voxels > 1e-3 ? sigma_voxels : 1e-3;
  f.radius = std::max(1, int(std::ceil(4.0 * s)));
  const int n = 2 * f.radius + 1;
  f.smooth.resize(n);
  f.derivative.resize(n);
  double sum = 0, moment = 0;
  for (int i = -f.radius; i <= f.radius; ++i) {
    const double g = std::exp(-0.5 * double(i) * double(i) / (s * s));
    f.smooth[i + f.radius] = g;
    f.derivative[i + f.radius] = double(i) * g;
    sum += g;
    moment += double(i) * double(i) * g;
  }
  if (moment == 0) {  // sigma so small that the Gaussian vanished off-centre: central differences
    f.derivative.assign(n, 0.0);
    f.derivative[f.radius - 1] = -0.5;
    f.derivative[f.radius + 1] = 0.5;
    moment = 1;
  }
  for (auto& w : f.smooth) w /= sum;
  for (auto& w : f.derivative) w /= moment;
  return f;
}

}  // namespace fluoro
