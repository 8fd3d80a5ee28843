#version 450
// The last pass of the gradient field: the z correlations of the three partial results (x
// derivative smoothed along y, x-smoothed y derivative, x-y smoothed) fused with the map from
// index-space derivatives to the CT physical frame, grad = D S^-1 d_index, written to the field's
// 3D image (w = 0), for the output slices of one slab. FIELD_BLOCK consecutive outputs along z
// per invocation.
#extension GL_GOOGLE_include_directive : require
#include "common/params.h"
#include "common/field.glsl"

layout(local_size_x = 64) in;
layout(std430, binding = 0) readonly buffer DxSy { float dx_sy[]; };
layout(std430, binding = 1) readonly buffer SxDy { float sx_dy[]; };
layout(std430, binding = 2) readonly buffer SxSy { float sx_sy[]; };
layout(std430, binding = 3) readonly buffer Weights { float weights[]; };
layout(binding = 4, rgba32f) writeonly uniform image3D field;
layout(push_constant) uniform Push { FinalPush pc; };

void main() {
  const ivec3 b = ivec3(gl_GlobalInvocationID);
  const int nz = pc.size.z, z_end = pc.z_first + pc.z_count;
  if (b.x >= pc.size.x || b.y >= pc.size.y || b.z >= (pc.z_count + FIELD_BLOCK - 1) / FIELD_BLOCK) return;
  const int at = pc.z_first + b.z * FIELD_BLOCK;
  const int slice = pc.size.x * pc.size.y, column = b.y * pc.size.x + b.x;
  const int r = pc.radius, taps = 2 * r + 1, ws = pc.weight_offset, wd = pc.weight_offset + taps;
  vec3 d0 = vec3(0.0), d1 = vec3(0.0), d2 = vec3(0.0), d3 = vec3(0.0);
  for (int o = -r; o <= r + FIELD_BLOCK - 1; ++o) {
    // Clamp-to-edge, and within the slices the slab holds (outputs past z_end, which are not
    // stored, would read further).
    const int q = (clamp(at + o, pc.size.w, min(nz - 1, z_end - 1 + r)) - pc.size.w) * slice + column;
    const vec3 v = vec3(dx_sy[q], sx_dy[q], sx_sy[q]);
#define TAP(j, acc)                                                                     \
    if (o - j + r >= 0 && o - j + r < taps) {                                           \
      const float s = weights[ws + o - j + r];                                          \
      acc = fma(vec3(s, s, weights[wd + o - j + r]), v, acc);                           \
    }
    TAP(0, d0) TAP(1, d1) TAP(2, d2) TAP(3, d3)
#undef TAP
  }
  const mat3 m = mat3(pc.m0.xyz, pc.m1.xyz, pc.m2.xyz);
  imageStore(field, ivec3(b.xy, at), vec4(m * d0, 0.0));
  if (at + 1 < z_end) imageStore(field, ivec3(b.xy, at + 1), vec4(m * d1, 0.0));
  if (at + 2 < z_end) imageStore(field, ivec3(b.xy, at + 2), vec4(m * d2, 0.0));
  if (at + 3 < z_end) imageStore(field, ivec3(b.xy, at + 3), vec4(m * d3, 0.0));
}
