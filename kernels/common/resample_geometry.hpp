#pragma once
// The grid a gradient field is resampled to (GradientFieldParams): same direction, starting at the
// old box's corner (continuous index -0.5 of the old grid is -0.5 of the new one), spacing s along
// every axis (or, with keep_coarser_axes, along the axes finer than s: the others keep theirs and
// their nodes), and enough voxels to cover the old box (so up to one new voxel past its far faces).
#include <algorithm>
#include <cmath>

#include "engine/volume.hpp"

namespace fluoro {

inline VolumeGeometry resampled_geometry(const VolumeGeometry& g, double s, bool keep_coarser_axes) {
  VolumeGeometry r = g;
  for (int a = 0; a < 3; ++a) {
    const double spacing = keep_coarser_axes ? std::max(s, g.spacing[a]) : s;
    const double extent = g.size[a] * g.spacing[a];
    r.size[a] = std::max(1, int(std::ceil(extent / spacing - 1e-9)));
    r.spacing[a] = spacing;
  }
  const Eigen::Vector3d corner = g.index_to_physical(Eigen::Vector3d::Constant(-0.5));
  r.origin = corner + g.direction * (0.5 * r.spacing);
  return r;
}

}  // namespace fluoro
