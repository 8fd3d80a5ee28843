#include "engine/attenuation.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace fluoro {

Volume hu_to_attenuation(Volume v, const AttenuationParams& params) {
  const float mw = float(params.mu_water_per_mm);
  // h < min_hu (a double) is h < the smallest float not below min_hu, for every float h: the
  // comparison in floats, which vectorises twice as wide, decides every voxel as in doubles.
  constexpr double kMax = std::numeric_limits<float>::max();
  constexpr float kInf = std::numeric_limits<float>::infinity();
  float min_hu = params.min_hu < -kMax ? -kInf : params.min_hu > kMax ? kInf : float(params.min_hu);
  if (double(min_hu) < params.min_hu) min_hu = std::nextafter(min_hu, std::numeric_limits<float>::infinity());
  tbb::parallel_for(tbb::blocked_range<size_t>(0, v.voxels.size(), 1 << 16), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i != r.end(); ++i) {
      const float h = v.voxels[i];
      v.voxels[i] = h < min_hu ? 0.0f : hu_to_mu(h, mw);
    }
  });
  return v;
}

}  // namespace fluoro
