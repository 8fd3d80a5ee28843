#pragma once
// Hounsfield units to linear attenuation per mm: mu = mu_water * max(0, 1 + HU / 1000).
#include "engine/volume.hpp"

namespace fluoro {

struct AttenuationParams {
  double mu_water_per_mm = 0.02;
  // Voxels below this HU become air (mu = 0): keeps only bone when set to, say, 200.
  // The default keeps every tissue.
  double min_hu = -1.0e30;
};

// Takes the volume by value so that a temporary (say, straight from read_volume) is converted in
// place, without a second buffer.
Volume hu_to_attenuation(Volume hu, const AttenuationParams& params = {});

}  // namespace fluoro
