#version 450
// Resampling of a gradient field to another grid (kernels/common/resample_geometry.hpp):
// destination voxel ijk is the trilinear read of the source at offset + scale * ijk.
#extension GL_GOOGLE_include_directive : require
#include "common/params.h"
#include "common/sampling.glsl"

layout(local_size_x = 64) in;
layout(binding = 0) uniform sampler3D src;
layout(binding = 1, rgba32f) writeonly uniform image3D dst;
layout(push_constant) uniform Push { ResamplePush pc; };

void main() {
  const ivec3 p = ivec3(gl_GlobalInvocationID);
  if (any(greaterThanEqual(p, pc.dst_size.xyz))) return;
  const vec3 x = fma(pc.scale.xyz, vec3(p), pc.offset.xyz);
  imageStore(dst, p, vec4(sample_trilinear(src, x, pc.inv_src_size.xyz).xyz, 0.0));
}
