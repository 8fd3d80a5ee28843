#version 450
// Which bricks of a volume hold data: one flag per brick of BRICK^3 voxels (the host dilates the
// flags and turns them into the distance map of common/skipping.glsl).
#extension GL_GOOGLE_include_directive : require
#include "common/params.h"
#include "common/skipping.glsl"

layout(local_size_x = 64) in;
layout(binding = 0) uniform sampler3D src;
layout(std430, binding = 1) writeonly buffer Occupied { uint occupied[]; };
layout(push_constant) uniform Push { BrickPush pc; };

void main() {
  const ivec3 b = ivec3(gl_GlobalInvocationID);
  if (any(greaterThanEqual(b, pc.bricks.xyz))) return;
  const ivec3 lo = b * BRICK, hi = min(lo + BRICK, pc.size.xyz);
  bool data = false;
  for (int z = lo.z; z < hi.z; ++z)
    for (int y = lo.y; y < hi.y; ++y)
      for (int x = lo.x; x < hi.x; ++x) {
        const vec4 v = texelFetch(src, ivec3(x, y, z), 0);
        data = data || (pc.size.w == 1 ? v.r != 0.0 : any(notEqual(v.xyz, vec3(0.0))));
      }
  occupied[(b.z * pc.bricks.y + b.y) * pc.bricks.x + b.x] = data ? 1u : 0u;
}
