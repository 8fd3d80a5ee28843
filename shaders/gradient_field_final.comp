#version 450
// The last pass of the gradient field: the z correlations of the three partial results (x
// derivative smoothed along y, x-smoothed y derivative, x-y smoothed) fused with the map from
// index-space derivatives to the CT physical frame, grad = D S^-1 d_index, written to the field's
// 3D image (w = 0).
#extension GL_GOOGLE_include_directive : require
#include "common/params.h"

layout(local_size_x = 64) in;
layout(std430, binding = 0) readonly buffer DxSy { float dx_sy[]; };
layout(std430, binding = 1) readonly buffer SxDy { float sx_dy[]; };
layout(std430, binding = 2) readonly buffer SxSy { float sx_sy[]; };
layout(std430, binding = 3) readonly buffer Weights { float weights[]; };
layout(binding = 4, rgba32f) writeonly uniform image3D field;
layout(push_constant) uniform Push { FinalPush pc; };

void main() {
  const ivec3 p = ivec3(gl_GlobalInvocationID);
  if (any(greaterThanEqual(p, pc.size.xyz))) return;
  const int taps = 2 * pc.radius + 1;
  vec3 d = vec3(0.0);
  for (int o = -pc.radius; o <= pc.radius; ++o) {
    const int z = clamp(p.z + o, 0, pc.size.z - 1);
    const int q = (z * pc.size.y + p.y) * pc.size.x + p.x;
    const float ws = weights[pc.weight_offset + o + pc.radius];
    const float wd = weights[pc.weight_offset + taps + o + pc.radius];
    d = fma(vec3(ws, ws, wd), vec3(dx_sy[q], sx_dy[q], sx_sy[q]), d);
  }
  const vec3 g = pc.m0.xyz * d.x + pc.m1.xyz * d.y + pc.m2.xyz * d.z;
  imageStore(field, p, vec4(g, 0.0));
}
