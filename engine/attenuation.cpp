#include "engine/attenuation.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>

namespace fluoro {

Volume hu_to_attenuation(Volume v, const AttenuationParams& params) {
  const float mw = float(params.mu_water_per_mm);
  const double min_hu = params.min_hu;
  tbb::parallel_for(tbb::blocked_range<size_t>(0, v.voxels.size(), 1 << 16), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i != r.end(); ++i) {
      const float h = v.voxels[i];
      v.voxels[i] = double(h) < min_hu ? 0.0f : mw * std::max(0.0f, 1.0f + h * 1e-3f);
    }
  });
  return v;
}

}  // namespace fluoro
