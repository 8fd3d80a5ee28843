#include "engine/volume.hpp"

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
  for (size_t n = 0; n < v.voxels.size(); ++n)
    if (!std::isfinite(v.voxels[n])) {
      const size_t nx = size_t(v.geometry.size.x()), ny = size_t(v.geometry.size.y());
      throw_input_error(what, "non-finite voxel value at index (" + std::to_string(n % nx) + ", " +
                                  std::to_string((n / nx) % ny) + ", " +
                                  std::to_string(n / (nx * ny)) + ")");
    }
}

}  // namespace fluoro
