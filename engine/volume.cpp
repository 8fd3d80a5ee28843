#include "engine/volume.hpp"

#include "engine/float_scan.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <cmath>

#include "engine/error.hpp"

namespace fluoro {

void validate_geometry(const VolumeGeometry& g, const std::string& what) {
  if ((g.size.array() <= 0).any())
    throw_input_error(what, "empty volume (size " + std::to_string(g.size.x()) + "x" +
                                std::to_string(g.size.y()) + "x" + std::to_string(g.size.z()) + ")");
  for (int a = 0; a < 3; ++a)
    if (!std::isfinite(g.spacing[a]) || g.spacing[a] <= 0)
      throw_input_error(what, "spacing along axis " + std::to_string(a) + " is " +
                                  std::to_string(g.spacing[a]) + " mm (must be positive)");
  if (!g.origin.allFinite()) throw_input_error(what, "origin is not finite");
  if (!g.direction.allFinite() ||
      !(g.direction.transpose() * g.direction).isApprox(Eigen::Matrix3d::Identity(), 1e-4))
    throw_input_error(what, "direction cosines are not orthonormal");
}

void validate_volume(const Volume& v, const std::string& what) {
  validate_geometry(v.geometry, what);
  if (v.voxels.size() != v.geometry.voxel_count())
    throw_input_error(what, "voxel buffer holds " + std::to_string(v.voxels.size()) +
                                " values, geometry needs " +
                                std::to_string(v.geometry.voxel_count()));
  // The first non-finite voxel, found in parallel.
  const size_t none = v.voxels.size();
  const size_t n = tbb::parallel_reduce(
      tbb::blocked_range<size_t>(0, v.voxels.size(), 1 << 16), none,
      [&](const tbb::blocked_range<size_t>& r, size_t found) {
        if (all_finite(v.voxels.data() + r.begin(), r.size())) return found;
        for (size_t i = r.begin(); i != r.end(); ++i)
          if (!std::isfinite(v.voxels[i])) return std::min(found, i);
        return found;
      },
      [](size_t a, size_t b) { return std::min(a, b); });
  if (n != none) {
    const size_t nx = size_t(v.geometry.size.x()), ny = size_t(v.geometry.size.y());
    throw_input_error(what, "non-finite voxel value at index (" + std::to_string(n % nx) + ", " +
                                std::to_string((n / nx) % ny) + ", " + std::to_string(n / (nx * ny)) + ")");
  }
}

}  // namespace fluoro
