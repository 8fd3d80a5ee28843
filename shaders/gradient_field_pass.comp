#version 450
// One separable pass of the Gaussian-derivative gradient field: a 1D correlation along one axis
// with the smoothing and/or the derivative filter (kernels/common/gaussian_derivative.hpp),
// clamp-to-edge. Each invocation computes FIELD_BLOCK consecutive outputs along the axis from
// FIELD_BLOCK + 2 radius inputs, each read once. Variant INPUT_IMAGE reads the attenuation
// volume's 3D image (the first pass); otherwise a float buffer from the previous pass.
#extension GL_GOOGLE_include_directive : require
#include "common/params.h"
#include "common/field.glsl"

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

void main() {
  const ivec3 unit = ivec3(equal(ivec3(pc.axis), ivec3(0, 1, 2)));
  const int n = idot(unit, pc.size.xyz);
  const ivec3 blocks = pc.size.xyz + unit * ((n + FIELD_BLOCK - 1) / FIELD_BLOCK - n);
  const ivec3 b = ivec3(gl_GlobalInvocationID);
  if (any(greaterThanEqual(b, blocks))) return;
  const int at = idot(unit, b) * FIELD_BLOCK;  // the first output along the axis
  const ivec3 p = b + unit * (at - idot(unit, b));
  const int index = (p.z * pc.size.y + p.y) * pc.size.x + p.x;
  const int stride = idot(unit, ivec3(1, pc.size.x, pc.size.x * pc.size.y));
  const int r = pc.radius, taps = 2 * r + 1, ws = pc.weight_offset, wd = pc.weight_offset + taps;
  vec4 s = vec4(0.0), d = vec4(0.0);
  for (int o = -r; o <= r + FIELD_BLOCK - 1; ++o) {
    const int q = clamp(at + o, 0, n - 1);
#ifdef INPUT_IMAGE
    const float v = texelFetch(src_image, p + unit * (q - at) + ivec3(0, 0, pc.size.w), 0).r;
#else
    const float v = src[index + (q - at) * stride];
#endif
    // Input at offset o contributes to output j with tap o - j + r.
#define TAP(j)                                            \
    if (o - j + r >= 0 && o - j + r < taps) {             \
      s[j] = fma(weights[ws + o - j + r], v, s[j]);       \
      d[j] = fma(weights[wd + o - j + r], v, d[j]);       \
    }
    TAP(0) TAP(1) TAP(2) TAP(3)
#undef TAP
  }
  for (int j = 0; j < FIELD_BLOCK && at + j < n; ++j) {
    if ((pc.flags & 1) != 0) smooth_out[index + j * stride] = s[j];
    if ((pc.flags & 2) != 0) derivative_out[index + j * stride] = d[j];
  }
}
