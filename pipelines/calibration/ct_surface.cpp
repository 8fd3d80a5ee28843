#include "pipelines/calibration/ct_surface.hpp"

#include <cmath>

#include "engine/error.hpp"
#include "pipelines/registration/bone_mesh.hpp"

namespace fluoro {

TriangleMesh ct_bone_surface(const Volume& hu, double iso_hu, double voxel_mm, const std::string& what) {
  if (!std::isfinite(iso_hu)) throw_input_error("iso_hu", "must be a number");
  if (!(voxel_mm > 0) || !std::isfinite(voxel_mm)) throw_input_error("voxel_mm", "must be a positive number");
  BoneMeshParams params;
  params.max_voxel_mm = voxel_mm;
  params.max_triangles = 2'000'000;
  const BoneMesh bone = bone_mesh_from_iso(hu, iso_hu, params, what);
  return TriangleMesh{bone.vertices, bone.triangles};
}

}  // namespace fluoro
