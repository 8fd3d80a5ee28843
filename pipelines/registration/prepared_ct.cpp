#include "pipelines/registration/prepared_ct.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>
#include <tbb/task_group.h>

#include <exception>

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
    tbb::parallel_for(tbb::blocked_range<size_t>(0, mu.voxels.size(), 1 << 16), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t i = r.begin(); i != r.end(); ++i) mu.voxels[i] = mu.voxels[i] > iso ? (mu.voxels[i] - iso) * scale : 0.0f;
    });
    return mu;
  }
  Volume mu = hu_to_attenuation(hu, {o.mu_water_per_mm});
  const VolumeGeometry& g = hu.geometry;
  const VolumeGeometry& m = mask->geometry;
  tbb::parallel_for(0, g.size.z(), [&](int k) {
    for (int j = 0; j < g.size.y(); ++j)
      for (int i = 0; i < g.size.x(); ++i) {
        const Eigen::Vector3d idx = m.physical_to_index(g.index_to_physical(Eigen::Vector3d(i, j, k)));
        const Eigen::Vector3i n(int(std::lround(idx.x())), int(std::lround(idx.y())), int(std::lround(idx.z())));
        const bool in = (n.array() >= 0).all() && (n.array() < m.size.array()).all() && mask->at(n.x(), n.y(), n.z()) != 0;
        if (!in) mu.at(i, j, k) = 0;
      }
  });
  return mu;
}

// `v` averaged over blocks of `f` voxels per axis, with the space beyond the volume counted as
// empty (attenuation 0), so that line integrals through the coarse grid keep their values.
Volume box_coarsened(const Volume& v, const Eigen::Vector3i& f) {
  const VolumeGeometry& g = v.geometry;
  Volume out;
  out.geometry = g;
  out.geometry.size = (g.size + f - Eigen::Vector3i::Ones()).cwiseQuotient(f);
  out.geometry.spacing = g.spacing.cwiseProduct(f.cast<double>());
  out.geometry.origin = g.index_to_physical((f.cast<double>() - Eigen::Vector3d::Ones()) * 0.5);
  out.voxels.assign(out.geometry.voxel_count(), 0.0f);
  const float weight = 1.0f / float(f.prod());
  // Output slices in parallel; each output voxel sums its block in the same order (k, j, i).
  tbb::parallel_for(0, out.geometry.size.z(), [&](int kz) {
    for (int k = kz * f.z(); k < std::min(kz * f.z() + f.z(), g.size.z()); ++k)
      for (int j = 0; j < g.size.y(); ++j)
        for (int i = 0; i < g.size.x(); ++i) out.at(i / f.x(), j / f.y(), kz) += weight * v.at(i, j, k);
  });
  return out;
}

}  // namespace

PreparedCt prepare_ct(Backend& backend, const Volume& hu, const RegistrationOptions& options, const Volume* mask) {
  const auto t0 = std::chrono::steady_clock::now();
  if (options.stages.empty()) throw std::invalid_argument("registration: no fine stages");
  PreparedCt p;
  // The mesh is mostly serial (ITK's marching cubes), the volumes mostly parallel: the mesh runs
  // beside them. Its error, if any, is reported first, as when it was built first.
  std::exception_ptr mesh_error, volumes_error;
  tbb::task_group mesh_task;
  mesh_task.run([&] {
    try {
      p.mesh = mask ? bone_mesh_from_mask(*mask, options.mesh, "mask")
                    : bone_mesh_from_iso(hu, options.bone_iso_hu, options.mesh, "CT");
    } catch (...) {
      mesh_error = std::current_exception();
    }
  });
  // The volumes: the bone's attenuation, what is not bone, the fine stages' gradient fields.
  auto volumes = [&] {
    Volume bone = bone_attenuation(hu, mask, options);
    if (std::all_of(bone.voxels.begin(), bone.voxels.end(), [](float v) { return v == 0.0f; }))
      throw InputError(mask ? std::string("mask: it covers no voxel of the CT")
                            : "CT: no voxel above the soft-tissue threshold of " + std::to_string(int(std::lround(options.tissue_hu))) + " HU");
    p.bone_mu = backend.upload(bone);
    // What the bone DRR lacks, in place of the bone (uploaded, its host copy is no longer needed).
    const float mw = float(options.mu_water_per_mm);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, bone.voxels.size(), 1 << 16), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t i = r.begin(); i != r.end(); ++i) bone.voxels[i] = std::max(0.0f, hu_to_mu(hu.voxels[i], mw) - bone.voxels[i]);
    });
    // It is rendered with a step of 3 mm into the correlation's reduced views (at most about
    // 256^2; fewer pixels for coarse CTs, reduced_view.hpp): an axis of 1 mm or finer
    // is box-averaged by the whole factor nearest 1.5 mm over its spacing (to 1.2 to 2 mm; a 0.96 x
    // 0.96 x 1.5 mm head CT's 7 M voxels to 1.8 M), which keeps a fine CT's preparation within its
    // memory goal (docs/benchmarks.md) and its expected correlation within 0.5 % (the 0.8 mm
    // pelvis phantom, fluoro_registration_bench's expected_correlation).
    Eigen::Vector3i factor;
    for (int a = 0; a < 3; ++a) factor[a] = std::max(1, int(std::lround(1.5 / bone.geometry.spacing[a])));
    p.non_bone_mu = backend.upload(factor == Eigen::Vector3i::Ones() ? bone : box_coarsened(bone, factor));
    bone = Volume();  // before the fields: the memory goal counts every buffer at once
    // A stage's grid coarser than the CT's finest spacing resamples the field; otherwise the field
    // stays on the CT's own grid. Axes coarser than the stage's grid keep the CT's spacing (thick
    // slices are not interpolated into thinner ones).
    const double finest = hu.geometry.spacing.minCoeff();
    for (const GprStage& s : options.stages) {
      p.gradients.push_back(
          backend.gradient_field(*p.bone_mu, {s.sigma_mm, s.grid_mm > finest * 1.01 ? s.grid_mm : 0.0, true}));
      if (s.gradient_floor > 0) p.gradients.back() = backend.floor_gradient(*p.gradients.back(), {s.gradient_floor});
    }
  };
  try {
    // Isolated: the volumes' parallel loops never take up the mesh's task while they wait, which
    // would hold them up for the mesh's whole length.
    tbb::this_task_arena::isolate(volumes);
  } catch (...) {
    volumes_error = std::current_exception();
  }
  mesh_task.wait();
  if (mesh_error) std::rethrow_exception(mesh_error);
  if (volumes_error) std::rethrow_exception(volumes_error);
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
