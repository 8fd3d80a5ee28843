#pragma once
// The isotropic grid a gradient field is resampled to: same direction, starting at the old box's
// corner (continuous index -0.5 of the old grid is -0.5 of the new one), spacing s, and enough
// voxels to cover the old box (so up to one new voxel past its far faces).
#include <cmath>

#include "engine/volume.hpp"

namespace fluoro {

inline VolumeGeometry isotropic_geometry(const VolumeGeometry& g, double s) {
  VolumeGeometry r = g;
  for (int a = 0; a < 3; ++a) {
    const double extent = g.size[a] * g.spacing[a];
    r.size[a] = std::max(1, int(std::ceil(extent / s - 1e-9)));
    r.spacing[a] = s;
  }
  const Eigen::Vector3d corner = g.index_to_physical(Eigen::Vector3d::Constant(-0.5));
  r.origin = corner + g.direction * Eigen::Vector3d::Constant(0.5 * s);
  return r;
}

}  // namespace fluoro
