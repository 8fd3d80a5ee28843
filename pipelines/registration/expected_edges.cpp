#include "pipelines/registration/expected_edges.hpp"

#include "pipelines/registration/edge_thinning.hpp"

namespace fluoro {

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

}  // namespace fluoro
