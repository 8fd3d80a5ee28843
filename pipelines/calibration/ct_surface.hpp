#pragma once
// The surface ICP registers digitised points to when the model is a CT (`fluoro icp --ct`, and
// `fluoro.icp(..., ct=)` in Python): the bone's iso-surface, built as the registration pipeline
// builds its mesh but finer, since ICP's accuracy is the surface's.
#include <string>

#include "engine/triangle_mesh.hpp"
#include "engine/volume.hpp"

namespace fluoro {

// The surface of {HU >= iso_hu} in the CT frame (mm), the CT box-averaged to about voxel_mm first
// (up to 2 million triangles). Throws InputError naming `what` when nothing reaches iso_hu, and
// naming "iso_hu" / "voxel_mm" for a non-finite iso value or a spacing that is not positive.
TriangleMesh ct_bone_surface(const Volume& hu, double iso_hu, double voxel_mm, const std::string& what);

}  // namespace fluoro
