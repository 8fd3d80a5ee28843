#include "pipelines/registration/validation_overlay.hpp"

#include <algorithm>

#include "pipelines/registration/expected_edges.hpp"

namespace fluoro {

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
