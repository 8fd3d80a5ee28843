#pragma once
// The expected-edge map (the seed's validation overlay): the gradient projection at every pixel,
// thinned by non-maximum suppression along its direction and thresholded.
#include "engine/backend.hpp"

namespace fluoro {

struct ExpectedEdgeParams {
  double step_mm = 1.0;
  // Keep maxima whose magnitude is at least this fraction of the image's largest magnitude.
  double relative_threshold = 0.1;
};

struct ExpectedEdges {
  Image magnitude;  // |expected gradient| per pixel
  ImageU8 mask;     // 255 on an expected edge, 0 elsewhere
};

ExpectedEdges expected_edges(Backend& backend, const DeviceVolume& gradient, const Pose& T_world_ct,
                             const PinholeCamera& camera, const ExpectedEdgeParams& params = {});

// Non-maximum suppression and threshold of a dense 2-channel gradient image (row-major).
ImageU8 thin_edges(const std::vector<Eigen::Vector2f>& gradient, int width, int height,
                   double relative_threshold);

// An RGB overlay: the grey image (mapped from [lo, hi]) with each mask drawn in its colour.
struct OverlayLayer {
  const ImageU8* mask;
  uint8_t r, g, b;
};
std::vector<uint8_t> overlay_rgb(const Image& grey, float lo, float hi,
                                 std::initializer_list<OverlayLayer> layers);

// The seed's validation overlay (fig. 6): the X-ray (grey, [lo, hi]) with the CT's expected edges
// at `before` in red and at `after` in green.
std::vector<uint8_t> validation_overlay(Backend& backend, const DeviceVolume& gradient, const PinholeCamera& camera,
                                        const Image& grey, float lo, float hi, const Pose& before, const Pose& after);

}  // namespace fluoro
