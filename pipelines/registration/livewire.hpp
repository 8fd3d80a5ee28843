#pragma once
// Livewire: bone contours from a few points clicked on an X-ray. Consecutive clicks are joined by
// the cheapest path along the image's edges (OpenCV's IntelligentScissorsMB, the livewire the seed
// used), so a user need not trace every pixel of an outline, only mark where it runs.
#include <Eigen/Core>
#include <vector>

#include "engine/image.hpp"

namespace fluoro {

// The pixels of the path through `clicks` in order, each segment snapped to the X-ray's edges
// (log domain or any other encoding: only edges matter). The clicks must lie in the image.
std::vector<Eigen::Vector2f> livewire_path(const Image& xray, const std::vector<Eigen::Vector2f>& clicks);

}  // namespace fluoro
