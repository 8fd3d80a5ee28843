#include "pipelines/registration/prepared_ct.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "engine/attenuation.hpp"
#include "engine/error.hpp"
#include "pipelines/registration/registration.hpp"

namespace fluoro {
namespace {

// Attenuation of bone only: the CT's mu where the mask (looked up at each voxel's physical
// position, nearest voxel) is non-zero, or the attenuation in excess of soft tissue's.
Volume bone_attenuation(const Volume& hu, const Volume* mask, const RegistrationOptions& o) {
  if (!mask) {
    // Continuous where HU crosses the threshold, so the field has no artificial edge there, only
    // the CT's own ones, of what is denser than soft tissue.
    Volume mu = hu;
    const float scale = float(o.mu_water_per_mm / 1000.0), iso = float(o.tissue_hu);
    for (float& v : mu.voxels) v = v > iso ? (v - iso) * scale : 0.0f;
    return mu;
  }
  Volume mu = hu_to_attenuation(hu, {o.mu_water_per_mm});
  const VolumeGeometry& g = hu.geometry;
  const VolumeGeometry& m = mask->geometry;
  for (int k = 0; k < g.size.z(); ++k)
    for (int j = 0; j < g.size.y(); ++j)
      for (int i = 0; i < g.size.x(); ++i) {
        const Eigen::Vector3d idx = m.physical_to_index(g.index_to_physical(Eigen::Vector3d(i, j, k)));
        const Eigen::Vector3i n(int(std::lround(idx.x())), int(std::lround(idx.y())), int(std::lround(idx.z())));
        const bool in = (n.array() >= 0).all() && (n.array() < m.size.array()).all() && mask->at(n.x(), n.y(), n.z()) != 0;
        if (!in) mu.at(i, j, k) = 0;
      }
  return mu;
}

}  // namespace

PreparedCt prepare_ct(Backend& backend, const Volume& hu, const RegistrationOptions& options, const Volume* mask) {
  const auto t0 = std::chrono::steady_clock::now();
  if (options.stages.empty()) throw std::invalid_argument("registration: no fine stages");
  PreparedCt p;
  p.mesh = mask ? bone_mesh_from_mask(*mask, options.mesh, "mask") : bone_mesh_from_iso(hu, options.bone_iso_hu, options.mesh, "CT");
  {
    Volume bone = bone_attenuation(hu, mask, options);
    if (std::all_of(bone.voxels.begin(), bone.voxels.end(), [](float v) { return v == 0.0f; }))
      throw InputError(mask ? std::string("mask: it covers no voxel of the CT")
                            : "CT: no voxel above the soft-tissue threshold of " + std::to_string(int(std::lround(options.tissue_hu))) + " HU");
    p.bone_mu = backend.upload(bone);
  }
  // A stage's grid coarser than the CT's finest spacing resamples the field; otherwise the field
  // stays on the CT's own grid. Axes coarser than the stage's grid keep the CT's spacing (thick
  // slices are not interpolated into thinner ones).
  const double finest = hu.geometry.spacing.minCoeff();
  for (const GprStage& s : options.stages) {
    p.gradients.push_back(
        backend.gradient_field(*p.bone_mu, {s.sigma_mm, s.grid_mm > finest * 1.01 ? s.grid_mm : 0.0, true}));
    if (s.gradient_floor > 0) p.gradients.back() = backend.floor_gradient(*p.gradients.back(), {s.gradient_floor});
  }
  p.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return p;
}

nlohmann::json preparation_settings(const RegistrationOptions& o, bool mask) {
  nlohmann::json stages = nlohmann::json::array();
  for (const GprStage& s : o.stages) {
    stages.push_back({{"sigma_mm", s.sigma_mm}, {"grid_mm", s.grid_mm}});
    // Only when set, so that files prepared without a floor stay valid.
    if (s.gradient_floor > 0) stages.back()["gradient_floor"] = s.gradient_floor;
  }
  return {{"bone", mask ? "mask" : "iso-value"},
          {"iso_hu", o.bone_iso_hu},
          {"tissue_hu", o.tissue_hu},
          {"mu_water_per_mm", o.mu_water_per_mm},
          {"mesh", {{"max_voxel_mm", o.mesh.max_voxel_mm}, {"max_triangles", o.mesh.max_triangles},
                    {"smoothing_iterations", o.mesh.smoothing_iterations}}},
          {"fine_stages", stages},
          // Since 2026-12-02 (a prepared file of an anisotropic CT made before has 1 mm z slices).
          {"field_axes_coarser_than_grid", "kept"}};
}

}  // namespace fluoro
