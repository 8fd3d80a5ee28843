#pragma once
// Hounsfield units to linear attenuation per mm: mu = mu_water * max(0, 1 + HU / 1000).
#include <algorithm>

#include "engine/volume.hpp"

namespace fluoro {

struct AttenuationParams {
  double mu_water_per_mm = 0.02;
  // Voxels below this HU become air (mu = 0): keeps only bone when set to, say, 200.
  // The default keeps every tissue.
  double min_hu = -1.0e30;
};

// One voxel's attenuation per mm, in floats as the volume's conversion below does it.
inline float hu_to_mu(float hu, float mu_water_per_mm) { return mu_water_per_mm * std::max(0.0f, 1.0f + hu * 1e-3f); }

// Takes the volume by value so that a temporary (say, straight from read_volume) is converted in
// place, without a second buffer.
Volume hu_to_attenuation(Volume hu, const AttenuationParams& params = {});

}  // namespace fluoro
