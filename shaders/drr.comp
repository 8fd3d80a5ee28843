#version 450
// DRR: the line integral of attenuation along each ray, h * sum_k mu(sample k) (the cpu and
// reference backends' midpoint rule over the clipped chord). One ray per invocation.
#extension GL_GOOGLE_include_directive : require
#include "common/params.h"
#include "common/geometry.glsl"
#include "common/sampling.glsl"

layout(local_size_x = RAY_GROUP) in;
layout(binding = 0) uniform sampler3D volume;
layout(std430, binding = 1) readonly buffer Rays { Ray rays[]; };
layout(std430, binding = 2) writeonly buffer LineIntegrals { float line_integral[]; };
layout(push_constant) uniform Push { MarchPush pc; };

void main() {
  const uint i = gl_GlobalInvocationID.x;
  if (i >= pc.ray_count) return;
  const Ray r = rays[i];
  const vec3 inv_size = 1.0 / vec3(textureSize(volume, 0));
  float sum = 0.0;
  for (int k = 0; k < r.n; ++k) sum += sample_trilinear(volume, sample_position(r, k), inv_size).r;
  line_integral[i] = sum * r.step_h.w;
}
