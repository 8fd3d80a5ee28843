// Empty-space skipping, exact (the cpu backend's scheme, kernels/cpu/ray_march.cpp): a distance
// map holds, per brick of BRICK^3 voxels, 0 where a sample whose lower trilinear corner lies in the
// brick may read a non-zero voxel, else the Chebyshev distance in bricks (capped) to the nearest
// such brick. A sample in a brick at distance d reads only zeros, and so does every sample within
// BRICK * (d - 1) voxels of it along every axis: a ray leaps over them.
#ifndef FLUORO_SHADERS_COMMON_SKIPPING_GLSL
#define FLUORO_SHADERS_COMMON_SKIPPING_GLSL

#define BRICK_SHIFT 2
#define BRICK (1 << BRICK_SHIFT)
// After a sample with data, this many further samples are read without consulting the map (in
// dense regions the lookup would cost more than it saves; reading a zero sample is always right).
#define DENSE_RUN 3

// Ray steps per voxel of travel along the fastest axis, for leap lengths.
float steps_per_voxel(Ray r) {
  const vec3 s = abs(r.step_h.xyz);
  return 1.0 / max(1e-6, max(s.x, max(s.y, s.z)));
}

// 0 when the sample at x may be non-zero; otherwise the number of steps (at least 1) to the
// next sample that may be.
int empty_steps(usampler3D distance_map, vec3 x, ivec3 size, float per_voxel) {
  const ivec3 corner = clamp(ivec3(floor(x)), ivec3(0), size - 1);
  const uint d = texelFetch(distance_map, corner >> BRICK_SHIFT, 0).r;
  if (d == 0u) return 0;
  return max(1, int(min(float(BRICK * (int(d) - 1)) * per_voxel, 1.0e6)));
}

#endif
