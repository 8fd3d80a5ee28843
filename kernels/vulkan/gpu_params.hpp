#pragma once
// The shaders' parameter structs as C++ (one definition: shaders/common/params.h), with their
// std430 layout pinned down: a change on one side that the other does not see fails to compile.
#include <cstddef>

#include "shaders/common/params.h"

namespace fluoro::vulkan::gpu {

static_assert(sizeof(vec4) == 16 && sizeof(ivec4) == 16);

static_assert(sizeof(Ray) == 48);
static_assert(offsetof(Ray, entry_t0) == 0);
static_assert(offsetof(Ray, step_h) == 16);
static_assert(offsetof(Ray, inv_len) == 32);
static_assert(offsetof(Ray, n) == 36);
static_assert(offsetof(Ray, dir_u) == 40);
static_assert(offsetof(Ray, dir_v) == 44);

static_assert(sizeof(ProjectionImage) == 32);
static_assert(offsetof(ProjectionImage, axis_v) == 16);

static_assert(sizeof(MarchPush) == 16);
static_assert(offsetof(MarchPush, ray_count) == 0);
static_assert(offsetof(MarchPush, first_group) == 4);
static_assert(offsetof(MarchPush, cos_max) == 8);

static_assert(sizeof(FilterPush) == 32);
static_assert(offsetof(FilterPush, axis) == 16);
static_assert(offsetof(FilterPush, radius) == 20);
static_assert(offsetof(FilterPush, weight_offset) == 24);
static_assert(offsetof(FilterPush, flags) == 28);

static_assert(sizeof(FinalPush) == 80);
static_assert(offsetof(FinalPush, m0) == 16);
static_assert(offsetof(FinalPush, m2) == 48);
static_assert(offsetof(FinalPush, radius) == 64);
static_assert(offsetof(FinalPush, weight_offset) == 68);
static_assert(offsetof(FinalPush, z_first) == 72);
static_assert(offsetof(FinalPush, z_count) == 76);

static_assert(sizeof(ResamplePush) == 64);
static_assert(offsetof(ResamplePush, offset) == 16);
static_assert(offsetof(ResamplePush, scale) == 32);
static_assert(offsetof(ResamplePush, inv_src_size) == 48);

static_assert(sizeof(BrickPush) == 32);
static_assert(offsetof(BrickPush, bricks) == 16);

// Rays per workgroup (RAY_GROUP in shaders/common/geometry.glsl), and threads per workgroup of
// the voxel passes (local_size_x of gradient_field_*.comp and resample.comp).
inline constexpr unsigned kRayGroup = 64;
inline constexpr unsigned kVoxelGroup = 64;
// Outputs per invocation of the gradient-field passes along their axis (FIELD_BLOCK in
// shaders/common/field.glsl).
inline constexpr int kFieldBlock = 4;

}  // namespace fluoro::vulkan::gpu
