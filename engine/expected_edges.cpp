#include "engine/expected_edges.hpp"

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

ExpectedEdges expected_edges(Backend& backend, const DeviceVolume& gradient, const Pose& T_world_ct,
                             const PinholeCamera& camera, const ExpectedEdgeParams& params) {
  std::vector<Eigen::Vector2f> pixels;
  pixels.reserve(size_t(camera.width) * size_t(camera.height));
  for (int y = 0; y < camera.height; ++y)
    for (int x = 0; x < camera.width; ++x) pixels.emplace_back(float(x), float(y));
  const std::vector<Eigen::Vector2f> per_view[] = {std::move(pixels)};
  const auto g = backend.gradient_projection(gradient, std::span(&T_world_ct, 1), std::span(&camera, 1),
                                             per_view, ProjectionParams{params.step_mm})[0];
  ExpectedEdges e;
  e.magnitude = Image(camera.width, camera.height);
  for (size_t i = 0; i < g.size(); ++i) e.magnitude.pixels[i] = g[i].norm();
  e.mask = thin_edges(g, camera.width, camera.height, params.relative_threshold);
  return e;
}

std::vector<uint8_t> overlay_rgb(const Image& grey, float lo, float hi,
                                 std::initializer_list<OverlayLayer> layers) {
  std::vector<uint8_t> rgb(grey.pixels.size() * 3);
  const float scale = hi > lo ? 255.0f / (hi - lo) : 0.0f;
  for (size_t i = 0; i < grey.pixels.size(); ++i) {
    const auto v = uint8_t(std::clamp((grey.pixels[i] - lo) * scale, 0.0f, 255.0f));
    rgb[3 * i] = rgb[3 * i + 1] = rgb[3 * i + 2] = v;
    for (const auto& l : layers)
      if (l.mask->pixels[i]) {
        rgb[3 * i] = l.r;
        rgb[3 * i + 1] = l.g;
        rgb[3 * i + 2] = l.b;
      }
  }
  return rgb;
}

std::vector<uint8_t> validation_overlay(Backend& backend, const DeviceVolume& gradient, const PinholeCamera& camera,
                                        const Image& grey, float lo, float hi, const Pose& before, const Pose& after) {
  const ExpectedEdges red = expected_edges(backend, gradient, before, camera);
  const ExpectedEdges green = expected_edges(backend, gradient, after, camera);
  return overlay_rgb(grey, lo, hi, {{&red.mask, 255, 40, 40}, {&green.mask, 40, 255, 40}});
}

}  // namespace fluoro
