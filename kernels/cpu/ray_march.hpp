#pragma once
// SIMD ray marching through a padded float volume, the inner loop of the cpu backend's DRR and
// gradient projection. Rays go in lockstep, one per SIMD lane (Highway picks AVX-512, AVX2, SSE4
// or scalar at run time).
#include <cstdint>

namespace fluoro::cpu {

// Up to kPacketRays rays, structure-of-arrays. Start points and directions are in the padded
// volume's continuous index space (voxel (0,0,0) of the volume is padded index (1,1,1)).
inline constexpr int kPacketRays = 64;
struct RayPacket {
  alignas(64) float entry_x[kPacketRays], entry_y[kPacketRays], entry_z[kPacketRays];
  alignas(64) float step_x[kPacketRays], step_y[kPacketRays], step_z[kPacketRays];  // dir * h
  alignas(64) float t0[kPacketRays], h[kPacketRays];
  alignas(64) int32_t n[kPacketRays];  // samples; 0 for a ray that misses (or an unused slot)
};

// A volume with one voxel of edge replication on every side, so trilinear reads anywhere in the
// box [-0.5, n - 0.5] never need a bounds check. Voxels are 16-bit fixed point (value = q * scale)
// in 64-bit words, one word per padded voxel, in one of two layouts:
// - scalar volumes (attenuation): the word at padded index w holds, from the low half-word up,
//   voxels w, w + 1 (the next along x), w + nx and w + nx + 1 (the next row): one 64-bit load
//   fetches the four x-y neighbours of a trilinear sample, so a sample costs two loads instead of
//   eight. Loads are the limiting cost of ray marching on CPUs; the price is four times the memory
//   of plain 16-bit voxels, which a scalar volume can afford.
// - vector volumes (gradient fields, vector_voxels): the word holds the voxel's own three
//   components (x, y, z, then 16 unused bits). A trilinear sample costs eight loads instead of the
//   six of three quad-layout components, but the field takes 8 bytes per voxel instead of 24:
//   fine fields of real CTs (10-40 million voxels) then stay three times closer to the caches,
//   and in a third of the memory.
struct PaddedGrid {
  const uint64_t* words = nullptr;
  bool vector_voxels = false;
  float scale[3] = {1, 1, 1};
  bool is_signed = false;  // int16 halves (gradients) rather than uint16 (attenuation)
  int nx = 0, ny = 0, nz = 0;  // padded sizes (volume size + 2)
  // Empty-space skipping: per brick of (1 << brick_shift)^3 padded voxels, 0 where a trilinear sample whose
  // lower corner lies in the brick can read a non-zero voxel, else the Chebyshev distance (in
  // bricks, capped) to the nearest such brick. Samples in empty bricks are exactly zero and are
  // skipped, leaping over runs of them. Null: no skipping.
  const int32_t* occupancy = nullptr;
  int bricks_x = 0, bricks_y = 0;
  int brick_shift = 2;  // bricks of 1 << brick_shift voxels a side (brick_shift_for)
  // The box of the occupied bricks (distance 0), in padded voxel positions: a sample whose
  // position lies outside [lo, hi) along some axis is zero, so the marchers march a group of rays
  // only over the steps at which one of them is inside. Used only with `occupancy`; lo >= hi
  // along an axis: nothing is occupied.
  float occupied_lo[3] = {0, 0, 0}, occupied_hi[3] = {0, 0, 0};
};

// The brick size for a volume of this voxel spacing, as a shift (bricks of 2 or 4 voxels a side):
// a finer brick skips more of the empty space around thin bone, a coarser one costs fewer
// occupancy reads per voxel a ray crosses.
int brick_shift_for(double smallest_spacing_mm);

// Exactly `count` outputs are written; the rest of the caller's arrays stay untouched.
// out[i] = h * sum_k mu(entry + (k + 0.5) * step) for rays 0 .. count-1 (the DRR line integral).
void march_line_integrals(const PaddedGrid& grid, const RayPacket& rays, int count, float* out);

// out_c[i] = h * sum_k t_k * grad_c(entry + (k + 0.5) * step), t_k = t0 + (k + 0.5) h: the
// distance-weighted gradient integral of the gradient projection (before the axis products).
// The grid holds vector voxels (a gradient field); march_line_integrals reads scalar ones.
// nearest: read the nearest voxel instead of interpolating.
void march_weighted_gradients(const PaddedGrid& grid, const RayPacket& rays, int count, bool nearest,
                              float* out_x, float* out_y, float* out_z);

// The instruction set (Highway's name) the marchers above are dispatched to now.
const char* march_target();

}  // namespace fluoro::cpu
