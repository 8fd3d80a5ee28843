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

}  // namespace fluoro
