#version 450
// One separable pass of the Gaussian-derivative gradient field: a 1D correlation along one axis
// with the smoothing and/or the derivative filter (kernels/common/gaussian_derivative.hpp),
// clamp-to-edge, one output voxel per invocation. Variant INPUT_IMAGE reads the attenuation
// volume's 3D image (the first pass); otherwise a float buffer from the previous pass.
#extension GL_GOOGLE_include_directive : require
#include "common/params.h"

layout(local_size_x = 64) in;
#ifdef INPUT_IMAGE
layout(binding = 0) uniform sampler3D src_image;
#else
layout(std430, binding = 0) readonly buffer Src { float src[]; };
#endif
layout(std430, binding = 1) readonly buffer Weights { float weights[]; };
layout(std430, binding = 2) writeonly buffer Smooth { float smooth_out[]; };
layout(std430, binding = 3) writeonly buffer Derivative { float derivative_out[]; };
layout(push_constant) uniform Push { FilterPush pc; };

int idot(ivec3 a, ivec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }

void main() {
  const ivec3 p = ivec3(gl_GlobalInvocationID);
  if (any(greaterThanEqual(p, pc.size.xyz))) return;
  // The axis as a unit vector and stride (no dynamic vector indexing: it spills on some
  // compilers, lavapipe's among them).
  const ivec3 unit = ivec3(equal(ivec3(pc.axis), ivec3(0, 1, 2)));
  const int n = idot(unit, pc.size.xyz);
  const int at = idot(unit, p);
  const int index = (p.z * pc.size.y + p.y) * pc.size.x + p.x;
  const int stride = idot(unit, ivec3(1, pc.size.x, pc.size.x * pc.size.y));
  const int taps = 2 * pc.radius + 1;
  float s = 0.0, d = 0.0;
  for (int o = -pc.radius; o <= pc.radius; ++o) {
    const int q = clamp(at + o, 0, n - 1);
#ifdef INPUT_IMAGE
    const float v = texelFetch(src_image, p + unit * (q - at), 0).r;
#else
    const float v = src[index + (q - at) * stride];
#endif
    s = fma(weights[pc.weight_offset + o + pc.radius], v, s);
    d = fma(weights[pc.weight_offset + taps + o + pc.radius], v, d);
  }
  if ((pc.flags & 1) != 0) smooth_out[index] = s;
  if ((pc.flags & 2) != 0) derivative_out[index] = d;
}
