#version 450
// DRR: the line integral of attenuation along each ray, h * sum_k mu(sample k) (the cpu and
// reference backends' midpoint rule over the clipped chord). One ray per invocation.
#extension GL_GOOGLE_include_directive : require
#include "common/params.h"
#include "common/geometry.glsl"
#include "common/sampling.glsl"
#include "common/skipping.glsl"

layout(local_size_x = RAY_GROUP) in;
layout(binding = 0) uniform sampler3D volume;
layout(binding = 1) uniform usampler3D distance_map;
layout(std430, binding = 2) readonly buffer Rays { Ray rays[]; };
layout(std430, binding = 3) writeonly buffer LineIntegrals { float line_integral[]; };
layout(push_constant) uniform Push { MarchPush pc; };

void main() {
  const uint i = gl_GlobalInvocationID.x;
  if (i >= pc.ray_count) return;
  const Ray r = rays[i];
  const ivec3 size = textureSize(volume, 0);
  const vec3 inv_size = 1.0 / vec3(size);
  const float per_voxel = steps_per_voxel(r);
  float sum = 0.0;
  int k = 0, dense = 0;
  while (k < r.n) {
    const vec3 x = sample_position(r, k);
    if (dense == 0) {
      const int skip = empty_steps(distance_map, x, size, per_voxel);
      if (skip > 0) {
        k += skip;
        continue;
      }
      dense = DENSE_RUN;
    } else {
      --dense;
    }
    sum += sample_trilinear(volume, x, inv_size).r;
    ++k;
  }
  line_integral[i] = sum * r.step_h.w;
}
