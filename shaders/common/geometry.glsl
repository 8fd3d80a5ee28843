// Ray geometry shared by the ray-marching shaders. Rays come set up by the host (see Ray in
// params.h); this file only walks them, in the same float arithmetic as the cpu backend.
#ifndef FLUORO_SHADERS_COMMON_GEOMETRY_GLSL
#define FLUORO_SHADERS_COMMON_GEOMETRY_GLSL

// Threads per workgroup of every ray-marching shader (one ray each). The host pads each
// (pose, view) image of a gradient projection to a multiple of it, so a workgroup never mixes
// images (and the gpr_score reduction of a workgroup belongs to one pose).
#define RAY_GROUP 64

// Sample k of ray r, continuous index space: entry + (k + 0.5) * step.
vec3 sample_position(Ray r, int k) {
  return fma(r.step_h.xyz, vec3(float(k) + 0.5), r.entry_t0.xyz);
}

// Its distance from the source in mm: t0 + (k + 0.5) * h.
float sample_distance(Ray r, int k) {
  return fma(float(k) + 0.5, r.step_h.w, r.entry_t0.w);
}

#endif
