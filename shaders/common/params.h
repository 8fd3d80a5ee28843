// The parameter structs the Vulkan backend's shaders read, one definition compiled as GLSL (by
// glslangValidator, through #include) and as C++ (kernels/vulkan/gpu_params.hpp, which
// static_asserts every size and offset). Only 4-byte scalars and 16-byte vec4/ivec4 appear, in
// an order that has the same std430 layout (storage buffers, push constants) and C++ layout.
#ifndef FLUORO_SHADERS_COMMON_PARAMS_H
#define FLUORO_SHADERS_COMMON_PARAMS_H

#ifdef __cplusplus
#include <cstdint>
namespace fluoro::vulkan::gpu {
struct vec4 { float x, y, z, w; };
struct ivec4 { int32_t x, y, z, w; };
using uint = uint32_t;
#endif

// One ray, set up on the host in double precision exactly as the cpu backend does
// (engine/ray_setup.hpp: make_pixel_ray): sample k is at entry + (k + 0.5) * step in continuous
// index space, at distance t0 + (k + 0.5) * h mm from the source.
struct Ray {
  vec4 entry_t0;  // xyz: the ray's entry point (continuous index); w: t0 (mm)
  vec4 step_h;    // xyz: index-space step per sample (dir * h); w: h (mm)
  float inv_len;  // 1 / |K^-1 p|
  int n;          // samples; 0 for a miss or a padding ray
  float dir_u;    // gpr_score: the edge direction the expected gradient should point along
  float dir_v;
};

// Per (pose, view) image of a gradient projection: the CT-frame motion of a point at unit depth
// per pixel column (axis_u) and row (axis_v).
struct ProjectionImage {
  vec4 axis_u;
  vec4 axis_v;
};

// Push constants of the ray marchers (drr.comp, gradient_projection.comp). A dispatch covers
// ray_count rays of the per-ray buffers (bound at the dispatch's first ray), in workgroups of 64;
// workgroup g of a dispatch is global workgroup first_group + g (the index into the per-group
// buffers, which are bound whole).
struct MarchPush {
  uint ray_count;
  uint first_group;
  float cos_max;  // gpr_score: cosine of the largest accepted deviation
  uint pad;
};

// Push constants of a separable pass of the gradient field (gradient_field_pass.comp): 1D
// correlation of one input along `axis` with the smoothing filter (written when want_smooth) and
// the derivative filter (when want_derivative), clamp-to-edge. Weights: smooth then derivative,
// 2 * radius + 1 each, at weight_offset in the weights buffer.
struct FilterPush {
  ivec4 size;  // xyz: voxels of the slab; w: its first slice in the input image (INPUT_IMAGE)
  int axis;
  int radius;
  int weight_offset;
  int flags;  // 1: write the smoothed output; 2: write the derivative output
};

// Push constants of the last pass (gradient_field_final.comp): the z correlations of the three
// partial results fused with the index-to-physical matrix D S^-1 (columns m0, m1, m2), for the
// output slices [z_first, z_first + z_count) of a slab whose intermediates hold slices from
// size.w on.
struct FinalPush {
  ivec4 size;  // xyz: the whole volume; w: the first slice the intermediate buffers hold
  vec4 m0;
  vec4 m1;
  vec4 m2;
  int radius;
  int weight_offset;
  int z_first;
  int z_count;
};

// Push constants of the isotropic resampling (resample.comp): destination voxel ijk reads the
// source at continuous index offset + scale * ijk (trilinear, clamp-to-edge).
struct ResamplePush {
  ivec4 dst_size;
  vec4 offset;
  vec4 scale;
  vec4 inv_src_size;  // 1 / source size per axis, for normalised texture coordinates
};

// Push constants of the brick occupancy pass (brick_occupancy.comp): one flag per brick of
// BRICK^3 voxels, set when any voxel of the brick is non-zero (size.w: 1 for a scalar volume, 3
// for a gradient field).
struct BrickPush {
  ivec4 size;
  ivec4 bricks;
};

#ifdef __cplusplus
}  // namespace fluoro::vulkan::gpu
#endif
#endif
