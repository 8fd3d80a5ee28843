#pragma once
// The cpu backend's resident volumes: float, one voxel of edge replication on every side (see
// PaddedGrid), components as separate arrays so each gather reads one array.
#include <memory>
#include <vector>

#include "engine/backend.hpp"
#include "kernels/cpu/ray_march.hpp"

namespace fluoro::cpu {

class CpuVolume final : public DeviceVolume {
 public:
  CpuVolume(const VolumeGeometry& g, int components, const void* owner);

  // Copies an unpadded component (i fastest) in and replicates its faces into the padding.
  void set_component(int c, const float* unpadded);
  // Reads voxel (i, j, k) of the unpadded volume.
  float at(int c, int i, int j, int k) const { return data_[size_t(c)][padded_index(i + 1, j + 1, k + 1)]; }
  // Trilinear at a continuous (unpadded) index, clamp-to-edge.
  float sample(int c, float x, float y, float z) const;
  PaddedGrid grid() const;

 private:
  size_t padded_index(int i, int j, int k) const {
    return (size_t(k) * size_t(ny_) + size_t(j)) * size_t(nx_) + size_t(i);
  }
  int nx_, ny_, nz_;
  std::vector<float> data_[3];
};

}  // namespace fluoro::cpu
