#include "engine/attenuation.hpp"

#include <algorithm>

namespace fluoro {

Volume hu_to_attenuation(const Volume& hu, const AttenuationParams& params) {
  Volume mu;
  mu.geometry = hu.geometry;
  mu.voxels.resize(hu.voxels.size());
  const double mw = params.mu_water_per_mm;
  std::transform(hu.voxels.begin(), hu.voxels.end(), mu.voxels.begin(), [&](float h) {
    if (h < params.min_hu) return 0.0f;
    return float(mw * std::max(0.0, 1.0 + double(h) / 1000.0));
  });
  return mu;
}

}  // namespace fluoro
