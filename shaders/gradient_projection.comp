#version 450
// Gradient projection (the expected image gradient d DRR / du, d DRR / dv of a pixel):
// (1 / |K^-1 p|) * h * sum_k t_k grad mu(sample k), projected on the image axes. Variants (one
// SPIR-V each, see shaders/CMakeLists.txt):
//   NEAREST   read the voxel nearest each sample instead of interpolating;
//   GPR_SCORE instead of the 2D vectors, write one partial score per workgroup: the sum of
//             |expected gradient| over its rays whose gradient lies within acos(cos_max) of the
//             ray's edge direction.
#extension GL_GOOGLE_include_directive : require
#include "common/params.h"
#include "common/geometry.glsl"
#include "common/sampling.glsl"
#include "common/skipping.glsl"

layout(local_size_x = RAY_GROUP) in;
layout(binding = 0) uniform sampler3D field;
layout(binding = 1) uniform usampler3D distance_map;
layout(std430, binding = 2) readonly buffer Rays { Ray rays[]; };
layout(std430, binding = 3) readonly buffer Images { ProjectionImage images[]; };
layout(std430, binding = 4) readonly buffer GroupImage { uint group_image[]; };
#ifdef GPR_SCORE
layout(std430, binding = 5) writeonly buffer Partial { float partial[]; };
shared float sums[RAY_GROUP];
#else
layout(std430, binding = 5) writeonly buffer Gradients { vec2 gradient[]; };
#endif
layout(push_constant) uniform Push { MarchPush pc; };

void main() {
  const uint i = gl_GlobalInvocationID.x;  // the host pads every image to whole workgroups
  const Ray r = rays[i];
  const ivec3 size = textureSize(field, 0);
  const vec3 inv_size = 1.0 / vec3(size);
  const float per_voxel = steps_per_voxel(r);
  vec3 acc = vec3(0.0);
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
#ifdef NEAREST
    const vec3 g = sample_nearest(field, x, size).xyz;
#else
    const vec3 g = sample_trilinear(field, x, inv_size).xyz;
#endif
    acc = fma(vec3(sample_distance(r, k)), g, acc);
    ++k;
  }
  acc *= r.step_h.w;
  const uint group = pc.first_group + gl_WorkGroupID.x;
  const ProjectionImage im = images[group_image[group]];
  const vec2 e = vec2(dot(acc, im.axis_u.xyz), dot(acc, im.axis_v.xyz)) * r.inv_len;
#ifdef GPR_SCORE
  const float m = length(e);
  sums[gl_LocalInvocationID.x] = (m > 0.0 && dot(e, vec2(r.dir_u, r.dir_v)) >= pc.cos_max * m) ? m : 0.0;
  barrier();
  for (uint s = RAY_GROUP / 2; s > 0; s >>= 1) {
    if (gl_LocalInvocationID.x < s) sums[gl_LocalInvocationID.x] += sums[gl_LocalInvocationID.x + s];
    barrier();
  }
  if (gl_LocalInvocationID.x == 0) partial[group] = sums[0];
#else
  gradient[i] = e;
#endif
}
