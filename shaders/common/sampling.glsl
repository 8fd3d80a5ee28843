// Volume reads with the semantics of the reference backend (kernels/reference): continuous index
// x addresses voxel centres at integers, and reads past the edge repeat the edge voxel
// (clamp-to-edge). Every ray sample lies in the box [-0.5, n - 0.5], where the two agree.
#ifndef FLUORO_SHADERS_COMMON_SAMPLING_GLSL
#define FLUORO_SHADERS_COMMON_SAMPLING_GLSL

// Trilinear through the sampler's linear filter (clamp-to-edge, normalised coordinates): voxel
// centre i sits at (i + 0.5) / n.
vec4 sample_trilinear(sampler3D volume, vec3 x, vec3 inv_size) {
  return textureLod(volume, (x + 0.5) * inv_size, 0.0);
}

// The voxel nearest x: floor(x + 0.5), clamped to the volume.
vec4 sample_nearest(sampler3D volume, vec3 x, ivec3 size) {
  const ivec3 i = clamp(ivec3(floor(x + 0.5)), ivec3(0), size - 1);
  return texelFetch(volume, i, 0);
}

#endif
