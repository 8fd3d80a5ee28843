#pragma once
// A picture to check a distal-locking result by eye: the X-ray in grey; the matched guide spheres
// circled in green with their GUIDE.json ids, other dark circles in yellow; the nail band's edges in
// cyan; the hole ellipses in magenta; the guide's axes (blue) and the holes' axes (red) projected.
#include <cstdint>
#include <vector>

#include "engine/camera.hpp"
#include "engine/distal_locking_models.hpp"
#include "engine/image.hpp"
#include "pipelines/distal_locking/distal_locking.hpp"

namespace fluoro {

// RGB pixels (interleaved, width x height x 3); `result` may be a failed one.
std::vector<uint8_t> distal_locking_overlay(const Image& image, const PinholeCamera& camera, const DrillGuideModel& guide,
                                            const NailModel& nail, const DistalLocking& result);

}  // namespace fluoro
