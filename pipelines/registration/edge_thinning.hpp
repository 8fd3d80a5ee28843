#pragma once
// Thin edges from a dense gradient image: non-maximum suppression along each pixel's gradient
// direction (bilinear neighbours), then a threshold relative to the largest magnitude.
#include <Eigen/Core>
#include <vector>

#include "engine/image.hpp"

namespace fluoro {

// `gradient`: row-major, width x height 2-vectors. 255 on a kept maximum, 0 elsewhere.
ImageU8 thin_edges(const std::vector<Eigen::Vector2f>& gradient, int width, int height, double relative_threshold);

}  // namespace fluoro
