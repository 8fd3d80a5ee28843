#pragma once
// The seed's validation overlay (fig. 6): an X-ray with the CT's expected edges drawn on it at the
// start and the registered pose, so a user sees whether the registration holds.
#include <cstdint>
#include <initializer_list>
#include <vector>

#include "engine/backend.hpp"

namespace fluoro {

// An RGB overlay: the grey image (mapped from [lo, hi]) with each mask drawn in its colour.
struct OverlayLayer {
  const ImageU8* mask;
  uint8_t r, g, b;
};
std::vector<uint8_t> overlay_rgb(const Image& grey, float lo, float hi, std::initializer_list<OverlayLayer> layers);

// The X-ray (grey, [lo, hi]) with the CT's expected edges at `before` in red and at `after` in green.
std::vector<uint8_t> validation_overlay(Backend& backend, const DeviceVolume& gradient, const PinholeCamera& camera,
                                        const Image& grey, float lo, float hi, const Pose& before, const Pose& after);

}  // namespace fluoro
