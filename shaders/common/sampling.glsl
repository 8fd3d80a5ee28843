// Volume reads with the semantics of the reference backend (kernels/reference): continuous index
// x addresses voxel centres at integers, and reads past the edge repeat the edge voxel
// (clamp-to-edge). Every ray sample lies in the box [-0.5, n - 0.5], where the two agree.
#ifndef FLUORO_SHADERS_COMMON_SAMPLING_GLSL
#define FLUORO_SHADERS_COMMON_SAMPLING_GLSL

// Set by the host (kernels/vulkan/vulkan_pipeline.cpp) on devices whose linear filter weights
// are too coarse (8-bit sub-texel precision): trilinear reads are then made by hand.
layout(constant_id = 0) const bool MANUAL_TRILINEAR = false;

// Trilinear through the sampler's linear filter (clamp-to-edge, normalised coordinates): voxel
// centre i sits at (i + 0.5) / n. By hand: the eight voxels around x, clamped to the volume, with
// float weights (the cpu and reference backends' arithmetic).
vec4 sample_trilinear(sampler3D volume, vec3 x, vec3 inv_size) {
  if (MANUAL_TRILINEAR) {
    const ivec3 last = textureSize(volume, 0) - 1;
    const vec3 lower = floor(x);
    const vec3 f = x - lower;
    const ivec3 a = clamp(ivec3(lower), ivec3(0), last), b = clamp(ivec3(lower) + 1, ivec3(0), last);
    const vec4 c00 = mix(texelFetch(volume, a, 0), texelFetch(volume, ivec3(b.x, a.y, a.z), 0), f.x);
    const vec4 c10 = mix(texelFetch(volume, ivec3(a.x, b.y, a.z), 0), texelFetch(volume, ivec3(b.x, b.y, a.z), 0), f.x);
    const vec4 c01 = mix(texelFetch(volume, ivec3(a.x, a.y, b.z), 0), texelFetch(volume, ivec3(b.x, a.y, b.z), 0), f.x);
    const vec4 c11 = mix(texelFetch(volume, ivec3(a.x, b.y, b.z), 0), texelFetch(volume, b, 0), f.x);
    return mix(mix(c00, c10, f.y), mix(c01, c11, f.y), f.z);
  }
  return textureLod(volume, (x + 0.5) * inv_size, 0.0);
}

// The voxel nearest x: floor(x + 0.5), clamped to the volume.
vec4 sample_nearest(sampler3D volume, vec3 x, ivec3 size) {
  const ivec3 i = clamp(ivec3(floor(x + 0.5)), ivec3(0), size - 1);
  return texelFetch(volume, i, 0);
}

#endif
