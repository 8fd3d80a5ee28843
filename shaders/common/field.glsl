// Shared by the gradient-field passes.
#ifndef FLUORO_SHADERS_COMMON_FIELD_GLSL
#define FLUORO_SHADERS_COMMON_FIELD_GLSL

// Outputs per invocation along the filter axis (register blocking: each input is read once for
// FIELD_BLOCK outputs). The TAP(j) unrolling in the passes assumes 4.
#define FIELD_BLOCK 4

int idot(ivec3 a, ivec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }

#endif
