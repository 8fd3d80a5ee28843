#include "pipelines/registration/edge_thinning.hpp"

#include <algorithm>
#include <cmath>

namespace fluoro {

ImageU8 thin_edges(const std::vector<Eigen::Vector2f>& g, int width, int height,
                   double relative_threshold) {
  ImageU8 mask(width, height, 0);
  float max_m = 0;
  for (const auto& v : g) max_m = std::max(max_m, v.norm());
  if (max_m <= 0) return mask;
  const float threshold = float(relative_threshold) * max_m;
  auto mag = [&](float u, float v) {  // bilinear magnitude, zero outside
    const int i = int(std::floor(u)), j = int(std::floor(v));
    const float fu = u - float(i), fv = v - float(j);
    float acc = 0;
    for (int dj = 0; dj < 2; ++dj)
      for (int di = 0; di < 2; ++di) {
        const int x = i + di, y = j + dj;
        if (x < 0 || y < 0 || x >= width || y >= height) continue;
        acc += (di ? fu : 1 - fu) * (dj ? fv : 1 - fv) * g[size_t(y) * size_t(width) + size_t(x)].norm();
      }
    return acc;
  };
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      const Eigen::Vector2f v = g[size_t(y) * size_t(width) + size_t(x)];
      const float m = v.norm();
      if (m < threshold) continue;
      const Eigen::Vector2f d = v / m;
      // A maximum along the gradient direction (ties broken towards the positive side).
      if (m > mag(float(x) + d.x(), float(y) + d.y()) && m >= mag(float(x) - d.x(), float(y) - d.y()))
        mask.at(x, y) = 255;
    }
  return mask;
}

}  // namespace fluoro
