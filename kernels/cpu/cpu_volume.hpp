#pragma once
// The cpu backend's resident volumes: padded by one voxel of edge replication, stored as 16-bit
// fixed point, scalar volumes in x-y neighbour quads and gradient fields as one word of three
// components per voxel (see PaddedGrid). The quantum is the
// component's largest magnitude / 65535 (uint16, non-negative data) or / 32767 (int16): a relative
// error of at most 1.5e-5 of that magnitude per voxel, far below CT noise.
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "engine/backend.hpp"
#include "kernels/cpu/default_init_allocator.hpp"
#include "kernels/cpu/ray_march.hpp"

namespace fluoro::cpu {

class CpuVolume final : public DeviceVolume {
 public:
  // Quantises the unpadded components (i fastest; 1 or 3 of them) and fills the padding and the
  // brick occupancy. Non-negative data takes uint16 quanta, anything else int16. Throws
  // InputError on a non-finite value.
  CpuVolume(const VolumeGeometry& g, const void* owner, const std::vector<const float*>& components);
  // A volume saved by save(): the quanta, scales and brick distances as they were, nothing
  // recomputed (Backend::load_volume). Throws InputError naming `what` when `bytes` do not hold
  // a volume of this geometry and component count.
  CpuVolume(const VolumeGeometry& g, const void* owner, int components, std::span<const uint8_t> bytes,
            const std::string& what);
  // Gradient field `source` with every voxel whose (dequantised) magnitude is below
  // relative_tolerance * (the largest voxel magnitude) zeroed, and the brick occupancy rebuilt, so
  // that the marchers skip what became empty (Op::gradient_floor). Quanta and scales are kept.
  CpuVolume(const CpuVolume& source, const void* owner, double relative_tolerance);
  // The resident form as bytes (little-endian): a 32-byte head (uint32 signed, uint32 vector,
  // float scale[3], int32 bricks x, y, z), the padded voxels (gradient fields: their 64-bit words;
  // scalar volumes: each word's own 16-bit quantum, the neighbour quads rebuilt on load; padded
  // to 8 bytes), then the int32 brick distances.
  std::vector<uint8_t> save() const;
  // Voxel (i, j, k) of the unpadded volume, dequantised.
  float at(int c, int i, int j, int k) const { return value(c, padded_index(i + 1, j + 1, k + 1)); }
  // Trilinear at a continuous (unpadded) index, clamp-to-edge.
  float sample(int c, float x, float y, float z) const;
  PaddedGrid grid() const;

  // Fraction of bricks that hold data (the rest is skipped by the ray marchers).
  double occupied_fraction() const;


 private:
  size_t padded_index(int i, int j, int k) const {
    return (size_t(k) * size_t(ny_) + size_t(j)) * size_t(nx_) + size_t(i);
  }
  void set_component(int c, const float* unpadded, float max_abs);
  void count_bricks();  // bricks_x_, _y_, _z_ from the padded sizes and brick_shift_
  void build_occupancy();   // the brick distances, then find_occupied_box
  void find_occupied_box();  // occupied_lo_, occupied_hi_ from the brick distances
  float value(int c, size_t padded) const {
    // Scalar volumes: the low half-word of the voxel's quad; vector ones: component c's half-word.
    const uint32_t low = uint32_t((words_[padded] >> (vector_ ? 16 * c : 0)) & 0xFFFFu);
    return scale_[c] * (is_signed_ ? float(int16_t(uint16_t(low))) : float(low));
  }
  int nx_, ny_, nz_;
  int brick_shift_;  // brick_shift_for the voxel spacing
  bool is_signed_ = false;
  float scale_[3] = {1, 1, 1};
  bool vector_ = false;          // three components: PaddedGrid's vector-voxel layout
  // One per padded voxel, sized unwritten: every constructor writes all of them.
  std::vector<uint64_t, DefaultInitAllocator<uint64_t>> words_;
  int bricks_x_ = 0, bricks_y_ = 0, bricks_z_ = 0;
  std::vector<int32_t> occupancy_;
  float occupied_lo_[3] = {0, 0, 0}, occupied_hi_[3] = {0, 0, 0};  // PaddedGrid::occupied_lo, _hi
};

}  // namespace fluoro::cpu
