#pragma once
// A 3D scalar or vector image with ITK geometry: voxel (i, j, k) sits at
// origin + direction * diag(spacing) * (i, j, k), in millimetres (see docs/conventions.md).
#include <Eigen/Core>
#include <array>
#include <cstddef>
#include <string>
#include <vector>

#include "engine/huge_page_allocator.hpp"

namespace fluoro {

struct VolumeGeometry {
  Eigen::Vector3i size{0, 0, 0};                          // voxels along i, j, k
  Eigen::Vector3d origin{0, 0, 0};                        // mm, centre of voxel (0, 0, 0)
  Eigen::Vector3d spacing{1, 1, 1};                       // mm
  Eigen::Matrix3d direction = Eigen::Matrix3d::Identity();  // columns: physical index axes

  size_t voxel_count() const { return size_t(size.x()) * size_t(size.y()) * size_t(size.z()); }
  // Continuous index <-> CT physical coordinates.
  Eigen::Vector3d index_to_physical(const Eigen::Vector3d& ijk) const {
    return origin + direction * spacing.cwiseProduct(ijk);
  }
  Eigen::Vector3d physical_to_index(const Eigen::Vector3d& x) const {
    return (direction.transpose() * (x - origin)).cwiseQuotient(spacing);
  }
  // The physical extent: voxels are boxes of one spacing centred on their index, so the volume
  // covers continuous indices [-0.5, n - 0.5] along each axis.
  Eigen::Vector3d physical_centre() const {
    return index_to_physical((size.cast<double>() - Eigen::Vector3d::Ones()) * 0.5);
  }
  size_t linear_index(int i, int j, int k) const {
    return (size_t(k) * size_t(size.y()) + size_t(j)) * size_t(size.x()) + size_t(i);
  }
};

// A volume's voxels: a vector whose large buffers sit on huge pages (huge_page_allocator.hpp).
using VoxelBuffer = std::vector<float, HugePageAllocator<float>>;
using VectorBuffer = std::vector<std::array<float, 3>, HugePageAllocator<std::array<float, 3>>>;

// Scalar voxels (HU or attenuation per mm), i fastest, then j, then k (ITK's buffer order).
struct Volume {
  VolumeGeometry geometry;
  VoxelBuffer voxels;

  float at(int i, int j, int k) const { return voxels[geometry.linear_index(i, j, k)]; }
  float& at(int i, int j, int k) { return voxels[geometry.linear_index(i, j, k)]; }
};

// Three components per voxel: the gradient of attenuation in the CT physical frame, 1/mm^2.
struct VectorField {
  VolumeGeometry geometry;
  VectorBuffer vectors;

  const std::array<float, 3>& at(int i, int j, int k) const {
    return vectors[geometry.linear_index(i, j, k)];
  }
};

// Throws InputError naming `what` when the geometry is unusable (empty, non-positive or
// non-finite spacing, direction not orthonormal) or when the voxel count disagrees with it.
void validate_geometry(const VolumeGeometry& g, const std::string& what);
void validate_volume(const Volume& v, const std::string& what);

}  // namespace fluoro
